// The voice comparison behind the default protocol's choice of TTS voice
// (README "Choosing the voice"): for every sentence of a corpus and every
// voice, the speaking rate, the duration, the objective intelligibility of
// the protocol's vocoded version against the clean one (STOI, ESTOI: the same
// library calls as `avsi vocode` and `avsi stoi`), and how far each stop's
// and fricative's acoustic onset after a vowel lies from the synthesiser's
// own label (core/onsets.h; the front end then aligns those labels to the
// onsets, so this column is the synthesiser's property). Prints a Markdown table; --csv writes per-sentence rows.
//
//   build/bench/tts_voices [--protocol P] [--corpus C] [--voices a,b] [--csv out.csv]
//
// Defaults: protocols/beskow2004-en.toml, its corpus, and the voices
// espeak:en-us, festival:cmu_us_slt_arctic_hts and festival:kal_diphone (each
// Festival voice only when installed). The vocoder settings are the
// protocol's [vocoder] bands, low_hz, high_hz and seed (other keys are
// refused here rather than ignored); each sentence's noise seed is derived
// from the sentence id as the stimulus builder derives it.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/onsets.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "avsi/core/tts.h"
#include "avsi/vocoder/stoi.h"
#include "avsi/vocoder/vocoder.h"

namespace {

using namespace avsi;

struct Row {
    std::string id;
    int words = 0;
    int syllables = 0;
    double speech_s = 0.0;  // first to last speech phone (internal pauses included)
    double file_s = 0.0;    // with the 0.15 s edge silences
    double stoi = 0.0, estoi = 0.0;
    std::vector<ObstruentOnset> onsets;
};

double percentile(std::vector<double> v, double p) {
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    const double x = p * double(v.size() - 1);
    const auto i = static_cast<std::size_t>(x);
    return i + 1 < v.size() ? v[i] + (x - double(i)) * (v[i + 1] - v[i]) : v[i];
}

double mean(const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += x;
    return v.empty() ? std::nan("") : s / double(v.size());
}

double sd(const std::vector<double>& v) {
    const double m = mean(v);
    double s = 0.0;
    for (double x : v) s += (x - m) * (x - m);
    return v.size() > 1 ? std::sqrt(s / double(v.size() - 1)) : 0.0;
}

int count_words(const std::string& text) {
    std::istringstream in(text);
    int n = 0;
    for (std::string w; in >> w;)
        if (std::any_of(w.begin(), w.end(), [](unsigned char c) { return std::isalnum(c); })) ++n;
    return n;
}

vocoder::VocoderSettings protocol_vocoder(const Protocol& protocol) {
    vocoder::VocoderSettings v;
    DiagnosticList problems;
    const ConfigSection& section = protocol.vocoder;
    v.bands = static_cast<int>(section.get_int("bands", v.bands, 1, 64, problems));
    v.low_hz = section.get_number("low_hz", v.low_hz, 1.0, 1e5, problems);
    v.high_hz = section.get_number("high_hz", v.high_hz, 1.0, 1e5, problems);
    v.seed = static_cast<std::uint64_t>(section.get_int("seed", static_cast<long long>(v.seed), 0,
                                                        std::numeric_limits<long long>::max(), problems));
    for (const auto& key : section.keys())
        if (key != "bands" && key != "low_hz" && key != "high_hz" && key != "seed")
            problems.add(protocol.path.string(), section.find(key)->line, section.find(key)->column,
                         "vocoder." + key, "expected only bands, low_hz, high_hz and seed (tts_voices maps no other key), got " + key);
    problems.throw_if_any();
    return v;
}

std::vector<Row> measure(const Corpus& corpus, const TtsSettings& tts, const vocoder::VocoderSettings& base) {
    std::vector<Row> rows(corpus.sentences.size());
    std::atomic<std::size_t> next{0};
    std::mutex error_mutex;
    std::exception_ptr error;
    const auto work = [&] {
        for (std::size_t i; (i = next.fetch_add(1)) < rows.size();) {
            try {
                const Sentence& s = corpus.sentences[i];
                const TtsResult r = synthesize_speech(s.text, tts);
                Row& row = rows[i];
                row.id = s.id;
                row.words = count_words(s.text);
                const auto& inventory = PhoneInventory::builtin();
                double first = -1.0, last = 0.0;
                for (const auto& p : r.phones) {
                    if (p.symbol == "sil") continue;
                    if (first < 0.0) first = p.start_s;
                    last = p.end_s;
                    if (inventory.is_vowel(p.symbol)) ++row.syllables;
                }
                row.speech_s = last - first;
                row.file_s = r.audio.duration_s();
                vocoder::VocoderSettings v = base;
                v.seed = derive_seed(base.seed, "vocoder/" + s.id);
                const Audio vocoded = vocoder::vocode(r.audio, v).audio;
                row.stoi = vocoder::stoi(r.audio, vocoded);
                row.estoi = vocoder::stoi(r.audio, vocoded, {.extended = true});
                row.onsets = obstruent_onsets(r.audio, r.phones);
            } catch (...) {
                std::lock_guard lock(error_mutex);
                if (!error) error = std::current_exception();
                return;
            }
        }
    };
    std::vector<std::thread> threads;
    const unsigned n = std::max(1u, std::thread::hardware_concurrency());
    for (unsigned t = 1; t < n; ++t) threads.emplace_back(work);
    work();
    for (auto& t : threads) t.join();
    if (error) std::rethrow_exception(error);
    return rows;
}

int run(int argc, char** argv) {
    std::string protocol_path = std::string(AVSI_PROTOCOLS_DIR) + "/beskow2004-en.toml";
    std::string corpus_path, csv_path;
    std::vector<std::string> voices;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError(a + " needs a value");
            return argv[++i];
        };
        if (a == "--protocol") protocol_path = value();
        else if (a == "--corpus") corpus_path = value();
        else if (a == "--csv") csv_path = value();
        else if (a == "--voices") {
            std::istringstream in(value());
            for (std::string v; std::getline(in, v, ',');) voices.push_back(v);
        } else throw UsageError("unknown option " + a + " (--protocol, --corpus, --voices, --csv)");
    }
    const Protocol protocol = load_protocol(protocol_path);
    const Corpus corpus = read_corpus(corpus_path.empty() ? protocol.corpus.sentences : std::filesystem::path(corpus_path));
    const vocoder::VocoderSettings base = protocol_vocoder(protocol);
    if (voices.empty()) {
        voices.push_back("espeak:en-us");
        for (const auto& v : installed_tts_voices(TtsEngine::Festival))
            if (v == "cmu_us_slt_arctic_hts" || v == "kal_diphone") voices.push_back("festival:" + v);
    }

    std::ofstream csv;
    if (!csv_path.empty()) {
        csv.open(csv_path);
        csv << "voice,id,words,syllables,speech_s,file_s,stoi,estoi,onsets,median_onset_offset_ms\n";
    }
    std::printf("%zu sentences of %s; vocoder: %d bands, %g-%g Hz (%s)\n\n", corpus.sentences.size(),
                (corpus_path.empty() ? protocol.corpus.sentences.string() : corpus_path).c_str(), base.bands,
                base.low_hz, base.high_hz, protocol_path.c_str());
    std::printf("| voice | engine, version | syllables/s | words/min | speech per sentence, s | STOI vocoded | ESTOI vocoded |"
                " stop/fricative onsets after a vowel: offset from label, ms, median [p5, p95] | within 10 ms |\n");
    std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for (const auto& spec : voices) {
        TtsSettings tts;
        set_tts_voice(tts, spec);
        tts.align_onsets = false;  // the synthesiser's own segment times (the audio is the same)
        const TtsVoiceInfo info = describe_tts_voice(tts);
        const std::vector<Row> rows = measure(corpus, tts, base);
        std::vector<double> syl_rate, wpm, speech, stoi, estoi, offsets;
        for (const auto& r : rows) {
            syl_rate.push_back(r.syllables / r.speech_s);
            wpm.push_back(60.0 * r.words / r.speech_s);
            speech.push_back(r.speech_s);
            stoi.push_back(r.stoi);
            estoi.push_back(r.estoi);
            std::vector<double> own;
            for (const auto& o : r.onsets) {
                offsets.push_back(1000.0 * o.offset_s());
                own.push_back(1000.0 * o.offset_s());
            }
            if (csv.is_open())
                csv << fmt::format("{},{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{},{:.1f}\n", spec, r.id, r.words,
                                   r.syllables, r.speech_s, r.file_s, r.stoi, r.estoi, r.onsets.size(),
                                   percentile(own, 0.5));
        }
        const auto within = std::count_if(offsets.begin(), offsets.end(), [](double d) { return std::fabs(d) <= 10.0; });
        std::printf("| %s | %s %s | %.2f ± %.2f | %.0f ± %.0f | %.2f ± %.2f | %.3f ± %.3f | %.3f ± %.3f | %+.1f [%+.1f, %+.1f] (n = %zu) | %.0f %% |\n",
                    spec.c_str(), info.engine.c_str(), info.engine_version.c_str(), mean(syl_rate), sd(syl_rate),
                    mean(wpm), sd(wpm), mean(speech), sd(speech), mean(stoi), sd(stoi), mean(estoi), sd(estoi),
                    percentile(offsets, 0.5), percentile(offsets, 0.05), percentile(offsets, 0.95), offsets.size(),
                    offsets.empty() ? 0.0 : 100.0 * double(within) / double(offsets.size()));
        std::fflush(stdout);
    }
    std::printf("\nmean ± SD over sentences; speech = first to last non-silent phone\n");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const avsi::UsageError& e) {
        std::fprintf(stderr, "tts_voices: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 1;
    }
}
