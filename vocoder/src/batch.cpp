// File and folder processing; see batch.h.
#include "avsi/vocoder/batch.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>

#include "avsi/core/audio_stream.h"
#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"

namespace avsi::vocoder {

namespace fs = std::filesystem;

std::vector<fs::path> list_wav_files(const fs::path& folder) {
    if (!fs::is_directory(folder)) throw InputError(folder, "expected a folder of WAV files, got no such folder");
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(folder)) {
        std::string ext = entry.path().extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
        if (entry.is_regular_file() && ext == ".wav") files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) throw InputError(folder, "expected WAV files (*.wav) in this folder, found none");
    return files;
}

LongTermSpectrum long_term_spectrum_of(const std::vector<fs::path>& files_or_folders) {
    std::vector<Audio> recordings;
    for (const fs::path& p : files_or_folders) {
        if (fs::is_directory(p))
            for (const fs::path& f : list_wav_files(p)) recordings.push_back(read_audio(f));
        else
            recordings.push_back(read_audio(p));
    }
    return long_term_spectrum(recordings);
}

namespace {

MixResult add_noise(const Audio& audio, const NoiseSettings& noise, const LongTermSpectrum* ltas,
                    const std::vector<double>* noise_samples, std::uint64_t seed) {
    MixSettings mix = noise.mix;
    mix.seed = seed;
    if (noise.kind == NoiseKind::SpeechShaped) {
        AVSI_ASSERT(ltas != nullptr);
        const auto shaped = speech_shaped_noise(*ltas, audio.frames(), audio.sample_rate_hz, seed);
        return mix_at_snr(audio, shaped, mix);
    }
    AVSI_ASSERT(noise_samples != nullptr);
    return mix_at_snr(audio, *noise_samples, mix);
}

}  // namespace

Audio process_audio(const Audio& input, const ProcessSettings& s, const LongTermSpectrum* ltas,
                    const std::vector<double>* noise_samples, std::uint64_t noise_seed, FileReport* report,
                    const std::string& source) {
    Audio audio = s.channels == ChannelMode::Mono ? mix_down(input, source, "before processing") : input;
    const bool noisy = s.noise.kind != NoiseKind::None;
    if (noisy && (s.noise.stage == NoiseStage::BeforeVocoding || !s.vocode)) {
        MixResult mixed = add_noise(audio, s.noise, ltas, noise_samples, noise_seed);
        audio = std::move(mixed.audio);
        if (report) report->mix_limit_gain_db = mixed.limit_gain_db;
    }
    if (s.vocode) {
        VocoderResult vocoded = vocode(audio, s.vocoder);
        audio = std::move(vocoded.audio);
        if (report) {
            report->vocoder_limit_gain_db = vocoded.limit_gain_db;
            report->selection = std::move(vocoded.selection);
        }
    }
    if (noisy && s.noise.stage == NoiseStage::AfterVocoding && s.vocode) {
        MixResult mixed = add_noise(audio, s.noise, ltas, noise_samples, noise_seed);
        audio = std::move(mixed.audio);
        if (report) report->mix_limit_gain_db = mixed.limit_gain_db;
    }
    if (report) report->duration_s = audio.duration_s();
    return audio;
}

namespace {

// Whether `input` can be processed file to file in blocks: vocoding alone,
// or a noise recording at the input's rate added before vocoding (or
// without it). Speech-shaped noise is made by one FFT over the whole
// length, noise at another rate is resampled whole, and noise added after
// vocoding would need the vocoded signal twice: those run in memory.
bool streamable(const ProcessSettings& s, const fs::path& input) {
    // A multi-channel input mixed down to mono (the default), or a
    // multi-channel noise recording, goes through mix_down's note in memory.
    const AudioFileReader in(input);
    if (in.channels() > 1 && s.channels == ChannelMode::Mono) return false;
    if (s.noise.kind == NoiseKind::None) return s.vocode;
    if (s.noise.kind != NoiseKind::File) return false;
    if (s.vocode && s.noise.stage == NoiseStage::AfterVocoding) return false;
    const AudioFileReader noise(s.noise.file);
    return noise.channels() == 1 && noise.sample_rate_hz() == in.sample_rate_hz();
}

// File to file in blocks (streamable() holds): memory bounded whatever the
// files' lengths; the vocoder's filters on `threads` threads (1 or 2).
void process_file_streaming(const fs::path& input, const fs::path& output, const ProcessSettings& s,
                            FileReport& report, unsigned threads) {
    AudioFileReader in(input);
    AudioFileWriter out(output, in.sample_rate_hz(), in.channels());
    std::optional<NoiseFile> noise;
    std::optional<MixedSource> mixed;
    AudioSource* source = &in;
    if (s.noise.kind == NoiseKind::File) {
        noise.emplace(s.noise.file);
        MixSettings mix = s.noise.mix;
        mix.seed = derive_seed(s.noise.mix.seed, input.filename().string());
        mixed.emplace(in, *noise, mix);
        report.mix_limit_gain_db = mixed->report().limit_gain_db;
        source = &*mixed;
    }
    if (s.vocode) {
        detail::StreamLimits limits;
        limits.threads = threads;
        VocoderReport vocoded = detail::vocode_stream(*source, out, s.vocoder, limits);
        report.vocoder_limit_gain_db = vocoded.limit_gain_db;
        report.selection = std::move(vocoded.selection);
    } else {
        std::vector<float> block(8192 * static_cast<std::size_t>(in.channels()));
        source->seek(0);
        while (const std::size_t n = source->read(block.data(), 8192)) out.write(block.data(), n);
    }
    out.commit();
    report.duration_s = static_cast<double>(in.frames()) / in.sample_rate_hz();
}

// Names the input file in diagnostics that name none.
[[noreturn]] void rethrow_naming(const InputError& e, const fs::path& input) {
    std::vector<Diagnostic> diagnostics = e.diagnostics();
    for (Diagnostic& d : diagnostics)
        if (d.path.empty()) d.path = input.string();
    throw InputError(std::move(diagnostics));
}

}  // namespace

FileReport process_file(const fs::path& input, const fs::path& output, const ProcessSettings& s) {
    FileReport report{input, output};
    try {
        if (streamable(s, input)) {
            process_file_streaming(input, output, s, report, 2);
            return report;
        }
    } catch (const InputError& e) {
        rethrow_naming(e, input);
    }
    try {
        const Audio audio = read_audio(input);
        std::optional<LongTermSpectrum> ltas;
        std::vector<double> noise;
        if (s.noise.kind == NoiseKind::SpeechShaped)
            ltas = s.noise.ltas_from.empty() ? long_term_spectrum({audio}) : long_term_spectrum_of(s.noise.ltas_from);
        if (s.noise.kind == NoiseKind::File) noise = load_noise(s.noise.file, audio.sample_rate_hz);
        // The same per-file noise seed as in a folder run.
        const std::uint64_t seed = derive_seed(s.noise.mix.seed, input.filename().string());
        const Audio out = process_audio(audio, s, ltas ? &*ltas : nullptr, &noise, seed, &report, input.string());
        write_audio(output, out);
    } catch (const InputError& e) {
        // Give diagnostics without a path the input file's name.
        rethrow_naming(e, input);
    }
    return report;
}

std::vector<FileReport> process_folder(const fs::path& input_folder, const fs::path& output_folder,
                                       const ProcessSettings& s, unsigned threads) {
    const std::vector<fs::path> files = list_wav_files(input_folder);
    if (fs::exists(output_folder) && fs::equivalent(input_folder, output_folder))
        throw InputError(output_folder, "expected an output folder different from the input folder");
    fs::create_directories(output_folder);
    // Shared inputs, computed once.
    std::optional<LongTermSpectrum> ltas;
    if (s.noise.kind == NoiseKind::SpeechShaped)
        ltas = long_term_spectrum_of(s.noise.ltas_from.empty() ? std::vector<fs::path>{input_folder}
                                                               : s.noise.ltas_from);
    std::mutex noise_mutex;
    std::map<int, std::vector<double>> noise_by_rate;  // noise file resampled per input rate

    if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
    threads = std::min<unsigned>(threads, static_cast<unsigned>(files.size()));
    std::vector<FileReport> reports(files.size());
    std::atomic<std::size_t> next{0};
    std::mutex error_mutex;
    std::vector<Diagnostic> problems;
    Progress progress("vocode", files.size());
    auto worker = [&] {
        for (std::size_t i = next++; i < files.size(); i = next++) {
            const fs::path output = output_folder / files[i].filename();
            try {
                FileReport report{files[i], output};
                if (streamable(s, files[i])) {
                    // Two threads for a file only when the files do not
                    // already run side by side.
                    process_file_streaming(files[i], output, s, report, threads >= 2 ? 1 : 2);
                } else {
                    const Audio audio = read_audio(files[i]);
                    const std::vector<double>* noise = nullptr;
                    if (s.noise.kind == NoiseKind::File) {
                        std::lock_guard lock(noise_mutex);
                        auto it = noise_by_rate.find(audio.sample_rate_hz);
                        if (it == noise_by_rate.end())
                            it = noise_by_rate
                                     .emplace(audio.sample_rate_hz, load_noise(s.noise.file, audio.sample_rate_hz))
                                     .first;
                        noise = &it->second;
                    }
                    const std::uint64_t seed = derive_seed(s.noise.mix.seed, files[i].filename().string());
                    const Audio out =
                        process_audio(audio, s, ltas ? &*ltas : nullptr, noise, seed, &report, files[i].string());
                    write_audio(output, out);
                }
                reports[i] = report;
            } catch (const InputError& e) {
                std::lock_guard lock(error_mutex);
                for (Diagnostic d : e.diagnostics()) {
                    if (d.path.empty()) d.path = files[i].string();
                    problems.push_back(std::move(d));
                }
            } catch (const std::exception& e) {
                std::lock_guard lock(error_mutex);
                problems.push_back(Diagnostic{files[i].string(), 0, 0, "", e.what()});
            }
            progress.advance();
        }
    };
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
    progress.finish();
    if (!problems.empty()) throw InputError(std::move(problems));
    return reports;
}

std::string describe(const NoiseSettings& noise) {
    if (noise.kind == NoiseKind::None) return "";
    std::string source;
    if (noise.kind == NoiseKind::SpeechShaped) {
        std::string from;
        for (const auto& p : noise.ltas_from) from += (from.empty() ? "" : ", ") + p.string();
        source = fmt::format("speech-shaped Gaussian noise with the long-term average spectrum (Welch, 2048-point "
                             "Hann frames, 50 % overlap) of {}; seeded per file from seed {} and the file name",
                             from.empty() ? "the input files" : from, noise.mix.seed);
    } else {
        source = fmt::format("the recording {} (an excerpt at a seeded offset when longer than the speech, looped "
                             "when shorter; seed {})",
                             noise.file.string(), noise.mix.seed);
    }
    return fmt::format("{:<22}{}\n{:<22}{} dB, speech level as RMS over {}; noise added {}\n", "Masking noise:", source,
                       "Signal-to-noise ratio:", noise.mix.snr_db,
                       noise.mix.reference == SnrReference::WholeSignal
                           ? "the whole signal"
                           : "20 ms frames within 40 dB of the loudest frame (pauses excluded)",
                       noise.stage == NoiseStage::BeforeVocoding ? "before vocoding (the mixture is vocoded)"
                                                                 : "after vocoding");
}

}  // namespace avsi::vocoder
