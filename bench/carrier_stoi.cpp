// The objective intelligibility of each vocoder carrier (docs/vocoder-carriers.md):
// every sentence of a corpus synthesised with the protocol's voice, vocoded
// with each carrier at each band count (the builder's per-sentence seeds,
// the protocol's band range), and scored against its clean version with
// STOI and ESTOI (the library calls behind `avsi vocode` and `avsi stoi`);
// with each carrier's vocoding speed (seconds of speech per second of one
// thread's CPU time, vocoding alone: CLOCK_THREAD_CPUTIME_ID, so other work
// on the machine does not count). Prints a Markdown table.
//
//   build/bench/carrier_stoi [--protocol P] [--bands 4,8,16]
//                            [--carriers noise,sine,low-noise,pulse-train,poisson]
//
// The pulse carriers run at the library's defaults (100 pulses/s, 100 µs,
// interleaved) unless --pulse-rate is given.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "avsi/core/tts.h"
#include "avsi/vocoder/stoi.h"
#include "avsi/vocoder/vocoder.h"

namespace {

using namespace avsi;

double mean(const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += x;
    return v.empty() ? std::nan("") : s / double(v.size());
}

// CPU seconds of the calling thread.
double thread_cpu_s() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

double sd(const std::vector<double>& v) {
    const double m = mean(v);
    double s = 0.0;
    for (double x : v) s += (x - m) * (x - m);
    return v.size() > 1 ? std::sqrt(s / double(v.size() - 1)) : 0.0;
}

std::vector<std::string> split(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string v; std::getline(in, v, ',');) out.push_back(v);
    return out;
}

// Runs work(i) for i in [0, n) on every core; rethrows the first error.
template <typename Work>
void parallel_for(std::size_t n, Work&& work) {
    std::atomic<std::size_t> next{0};
    std::mutex error_mutex;
    std::exception_ptr error;
    const auto loop = [&] {
        for (std::size_t i; (i = next.fetch_add(1)) < n;) {
            try {
                work(i);
            } catch (...) {
                std::lock_guard lock(error_mutex);
                if (!error) error = std::current_exception();
                return;
            }
        }
    };
    std::vector<std::thread> threads;
    for (unsigned t = 1; t < std::max(1u, std::thread::hardware_concurrency()); ++t) threads.emplace_back(loop);
    loop();
    for (auto& t : threads) t.join();
    if (error) std::rethrow_exception(error);
}

struct Cell {
    std::vector<double> stoi, estoi;
    double vocode_s = 0.0;  // thread CPU time spent vocoding
};

Cell measure(const std::vector<Audio>& clean, const std::vector<std::string>& ids,
             const vocoder::VocoderSettings& base) {
    Cell cell;
    cell.stoi.resize(clean.size());
    cell.estoi.resize(clean.size());
    std::vector<double> seconds(clean.size());
    parallel_for(clean.size(), [&](std::size_t i) {
        vocoder::VocoderSettings v = base;
        v.seed = derive_seed(base.seed, "vocoder/" + ids[i]);
        const double start = thread_cpu_s();
        const Audio vocoded = vocoder::vocode(clean[i], v).audio;
        seconds[i] = thread_cpu_s() - start;
        cell.stoi[i] = vocoder::stoi(clean[i], vocoded);
        cell.estoi[i] = vocoder::stoi(clean[i], vocoded, {.extended = true});
    });
    for (double s : seconds) cell.vocode_s += s;
    return cell;
}

int run(int argc, char** argv) {
    std::string protocol_path = std::string(AVSI_PROTOCOLS_DIR) + "/beskow2004-en.toml";
    std::vector<std::string> carriers{"noise", "sine", "low-noise", "pulse-train", "poisson"};
    std::vector<int> band_counts{4, 8, 16};
    double pulse_rate_hz = vocoder::VocoderSettings{}.pulse_rate_hz;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError(a + " needs a value");
            return argv[++i];
        };
        if (a == "--protocol") protocol_path = value();
        else if (a == "--carriers") carriers = split(value());
        else if (a == "--pulse-rate") pulse_rate_hz = std::stod(value());
        else if (a == "--bands") {
            band_counts.clear();
            for (const auto& b : split(value())) band_counts.push_back(std::stoi(b));
        } else throw UsageError("unknown option " + a + " (--protocol, --bands, --carriers, --pulse-rate)");
    }
    const Protocol protocol = load_protocol(protocol_path);
    const Corpus corpus = read_corpus(protocol.corpus.sentences);
    TtsSettings tts;
    tts.engine = protocol.corpus.tts_engine;
    tts.voice = protocol.corpus.tts_voice;
    std::vector<Audio> clean(corpus.sentences.size());
    std::vector<std::string> ids;
    for (const auto& s : corpus.sentences) ids.push_back(s.id);
    parallel_for(clean.size(), [&](std::size_t i) { clean[i] = synthesize_speech(corpus.sentences[i].text, tts).audio; });
    double speech_s = 0.0;
    for (const auto& a : clean) speech_s += a.duration_s();
    std::printf("%zu sentences (%.1f s of speech, %d Hz) of %s, voice %s; 100-5000 Hz, Greenwood spacing, "
                "half-wave rectified envelopes at 160 Hz, causal 4th-order filters\n\n",
                clean.size(), speech_s, clean.empty() ? 0 : clean[0].sample_rate_hz,
                protocol.corpus.sentences.string().c_str(), tts_voice_spec(tts).c_str());
    std::printf("| carrier | bands | STOI | ESTOI | vocoding, × real time (one thread, CPU time) |\n| --- | --- | --- | --- | --- |\n");
    for (const auto& name : carriers)
        for (const int bands : band_counts) {
            vocoder::VocoderSettings v;
            v.bands = bands;
            v.carrier = vocoder::parse_carrier_type(name, "--carriers");
            v.pulse_rate_hz = pulse_rate_hz;
            v.seed = protocol.seed;
            const Cell cell = measure(clean, ids, v);
            std::printf("| %s | %d | %.3f ± %.3f | %.3f ± %.3f | %.0f |\n", name.c_str(), bands, mean(cell.stoi),
                        sd(cell.stoi), mean(cell.estoi), sd(cell.estoi), speech_s / cell.vocode_s);
            std::fflush(stdout);
        }
    std::printf("\nmean ± SD over sentences\n");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const avsi::UsageError& e) {
        std::fprintf(stderr, "carrier_stoi: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 1;
    }
}
