// `avsi mix`: masking noise (speech-shaped or a recording) added to speech
// at a given SNR, without vocoding; over a file or a folder (--batch).
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/vocoder/batch.h"
#include "command.h"
#include "one_of.h"
#include "vocoder_choices.h"

namespace avsi::cli {
namespace {

namespace fs = std::filesystem;
using namespace avsi::vocoder;

struct MixOptions {
    std::string input, output, noise, snr_reference = "whole";
    std::vector<std::string> ltas_from;
    double snr_db = 0.0;
    std::uint64_t seed = 1;
    bool batch = false, report = false;
    unsigned threads = 0;
    std::string channels = "mono";
};

int run_mix(const MixOptions& o) {
    ProcessSettings s;
    s.vocode = false;
    s.channels = parse_channel_mode(o.channels);
    s.noise.kind = o.noise == "speech-shaped" ? NoiseKind::SpeechShaped : NoiseKind::File;
    if (s.noise.kind == NoiseKind::File) {
        if (!fs::exists(o.noise))
            throw InputError(fs::path(o.noise), "--noise: expected \"speech-shaped\" or an existing noise file");
        s.noise.file = o.noise;
    }
    s.noise.mix.snr_db = o.snr_db;
    s.noise.mix.reference = parse_snr_reference(o.snr_reference, "--snr-reference");
    s.noise.mix.seed = o.seed;
    for (const auto& p : o.ltas_from) s.noise.ltas_from.emplace_back(p);
    if (o.report) fmt::print("{}", describe(s.noise));
    if (o.batch) {
        const auto reports = process_folder(o.input, o.output, s, o.threads);
        log_info("wrote {} files to {}", reports.size(), o.output);
    } else {
        process_file(o.input, o.output, s);
        log_info("wrote {}", o.output);
    }
    return 0;
}

const bool registered_mix = register_command({
    "mix",
    "Add masking noise (speech-shaped or a recording) to speech at a given SNR, without vocoding",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<MixOptions>();
        sub.add_option("input", o->input, "Input WAV file (a folder with --batch)")->required();
        sub.add_option("output", o->output, "Output WAV file (a folder with --batch)")->required();
        sub.add_option("--noise", o->noise, "speech-shaped, or a noise WAV file")->required();
        sub.add_option("--snr-db", o->snr_db, "Speech-to-noise ratio in dB")->required();
        sub.add_option("--snr-reference", o->snr_reference,
                       "Speech level over the whole signal (whole) or over active 20 ms frames (active)")
            ->capture_default_str()
            ->check(one_of(snr_reference_names()));
        sub.add_option("--ltas-from", o->ltas_from,
                       "WAV files or folders whose long-term spectrum shapes speech-shaped noise (default: the inputs)");
        sub.add_option("--seed", o->seed, "Seed of the noise (per file: derived from it and the file name in --batch)")
            ->capture_default_str();
        sub.add_flag("--batch", o->batch, "Process every .wav in the input folder into the output folder, on all cores");
        sub.add_flag("--report", o->report, "Print the noise settings for a methods section");
        sub.add_option("--threads", o->threads, "Threads for --batch (0: all cores)")->capture_default_str();
        sub.add_option("--channels", o->channels,
                       "Several channels: mono (mixed down first, a note says so) or keep (the same noise added to "
                       "every channel)")
            ->capture_default_str()
            ->check(one_of(channel_mode_names()));
        return [o] { return run_mix(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
