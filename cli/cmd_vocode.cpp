// `avsi vocode`: the noise-excited channel vocoder over one WAV file or a
// folder (all cores), with optional masking noise and a methods report.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/audio.h"
#include "avsi/core/audio_stream.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/vocoder/batch.h"
#include "ci_options.h"
#include "command.h"
#include "one_of.h"
#include "vocoder_choices.h"

namespace avsi::cli {
namespace {

namespace fs = std::filesystem;
using namespace avsi::vocoder;

struct VocodeOptions {
    std::string input, output;
    bool batch = false;
    VocoderSettings v;
    std::string spacing = "greenwood", envelope = "rectify", carrier = "noise";
    std::vector<double> edges_hz;
    bool no_refilter = false;
    std::string noise, snr_reference = "whole", noise_stage = "before";
    std::vector<std::string> ltas_from;
    double snr_db = 0.0;
    bool report = false;
    unsigned threads = 0;
    std::string channels = "mono";
    CiOptionNames ci;
    std::string selection_log;
};

int run_vocode(const VocodeOptions& o, const CLI::App& sub) {
    ProcessSettings s;
    s.channels = parse_channel_mode(o.channels);
    s.vocoder = o.v;
    s.vocoder.spacing = parse_band_spacing(o.spacing, "--spacing");
    s.vocoder.envelope = parse_envelope_method(o.envelope, "--envelope");
    s.vocoder.carrier = parse_carrier_type(o.carrier, "--carrier");
    s.vocoder.refilter_carrier = !o.no_refilter;
    apply_ci_options(o.ci, s.vocoder);
    if (!o.selection_log.empty() && (s.vocoder.n_of_m == 0 || o.batch))
        throw UsageError("--selection-log needs --n-of-m and one input file");
    if (!o.edges_hz.empty()) {
        for (const char* opt : {"--bands", "--low-hz", "--high-hz", "--spacing"})
            if (sub.count(opt) > 0)
                throw UsageError(fmt::format("--edges-hz gives the bands and their range; do not combine it with {}", opt));
        if (o.edges_hz.size() < 2) throw UsageError("--edges-hz needs at least two edges (one band)");
        s.vocoder.spacing = BandSpacing::Explicit;
        s.vocoder.edges_hz = o.edges_hz;
        s.vocoder.bands = static_cast<int>(o.edges_hz.size()) - 1;
        s.vocoder.low_hz = o.edges_hz.front();
        s.vocoder.high_hz = o.edges_hz.back();
    }
    if (!o.noise.empty()) {
        s.noise.kind = o.noise == "speech-shaped" ? NoiseKind::SpeechShaped : NoiseKind::File;
        if (s.noise.kind == NoiseKind::File) {
            if (!fs::exists(o.noise))
                throw InputError(fs::path(o.noise), "--noise: expected \"speech-shaped\" or an existing noise file");
            s.noise.file = o.noise;
        }
        if (sub.count("--snr-db") == 0) throw UsageError("--noise needs --snr-db");
        s.noise.mix.snr_db = o.snr_db;
        s.noise.mix.reference = parse_snr_reference(o.snr_reference, "--snr-reference");
        s.noise.mix.seed = o.v.seed;
        s.noise.stage = o.noise_stage == "before" ? NoiseStage::BeforeVocoding : NoiseStage::AfterVocoding;
        for (const auto& p : o.ltas_from) s.noise.ltas_from.emplace_back(p);
    } else if (sub.count("--snr-db") > 0) {
        throw UsageError("--snr-db needs --noise speech-shaped|FILE");
    }

    // Validate against the (first) input's rate before any work.
    const fs::path first = o.batch ? list_wav_files(o.input).front() : fs::path(o.input);
    const int rate = AudioFileReader(first).sample_rate_hz();
    validate_settings(s.vocoder, rate, "command line");
    if (o.report) fmt::print("{}{}", describe(s.vocoder, rate), describe(s.noise));

    if (o.batch) {
        const auto reports = process_folder(o.input, o.output, s, o.threads);
        std::size_t scaled = 0;
        for (const auto& r : reports) scaled += r.vocoder_limit_gain_db < 0.0 || r.mix_limit_gain_db < 0.0;
        log_info("wrote {} files to {}{}", reports.size(), o.output,
                 scaled ? fmt::format(" ({} scaled down to avoid clipping)", scaled) : std::string());
    } else {
        const FileReport r = process_file(o.input, o.output, s);
        if (r.vocoder_limit_gain_db < 0.0)
            log_warning("vocoder: the output peaked above full scale; scaled the whole output by {:.2f} dB to "
                        "avoid clipping",
                        r.vocoder_limit_gain_db);
        log_info("wrote {} ({:.2f} s)", o.output, r.duration_s);
        if (!o.selection_log.empty()) {
            write_text_file(o.selection_log, selection_csv(r.selection, s.vocoder.selection_frame_rate_hz));
            log_info("wrote {} ({} frames)", o.selection_log, r.selection.size());
        }
    }
    return 0;
}

const bool registered_vocode = register_command({
    "vocode",
    "Noise-excited channel vocoder (Shannon et al. 1995) over a WAV file or a folder, with optional masking noise",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<VocodeOptions>();
        sub.add_option("input", o->input, "Input WAV file (a folder with --batch)")->required();
        sub.add_option("output", o->output, "Output WAV file (a folder with --batch)")->required();
        sub.add_flag("--batch", o->batch, "Process every .wav in the input folder into the output folder, on all cores");
        sub.add_option("--bands", o->v.bands, "Number of analysis bands")->capture_default_str()->check(CLI::Range(1, 64));
        sub.add_option("--low-hz", o->v.low_hz, "Lower edge of the lowest band (Hz)")->capture_default_str();
        sub.add_option("--high-hz", o->v.high_hz, "Upper edge of the highest band (Hz), below Nyquist")->capture_default_str();
        sub.add_option("--spacing", o->spacing, "Band spacing: greenwood, log or linear")
            ->capture_default_str()
            ->check(one_of(band_spacing_names()));
        sub.add_option("--edges-hz", o->edges_hz, "Explicit band edges in Hz, comma-separated (sets bands and range)")
            ->delimiter(',');
        sub.add_option("--order", o->v.filter_order,
                       "Butterworth prototype order of each band-pass (2·order poles, 6·order dB/octave)")
            ->capture_default_str()->check(CLI::Range(1, 16));
        sub.add_flag("--zero-phase", o->v.zero_phase, "Filter forward and backward (no phase shift, doubled slopes)");
        sub.add_option("--envelope", o->envelope, "Envelope: rectify (half-wave), full-wave or hilbert")
            ->capture_default_str()
            ->check(one_of(envelope_method_names()));
        sub.add_option("--envelope-cutoff-hz", o->v.envelope_cutoff_hz, "Envelope low-pass cutoff (Hz)")->capture_default_str();
        sub.add_option("--envelope-order", o->v.envelope_filter_order, "Envelope Butterworth low-pass order")
            ->capture_default_str()->check(CLI::Range(1, 16));
        sub.add_option("--carrier", o->carrier, "Carrier: noise, sine, low-noise, pulse-train or poisson")
            ->capture_default_str()
            ->check(one_of(carrier_type_names()));
        add_ci_options(sub, o->v, o->ci);
        sub.add_option("--selection-log", o->selection_log,
                       "With --n-of-m: write the bands kept in each frame to this CSV (frame,start_s,bands)");
        sub.add_flag("--prefilter-carrier", o->v.prefilter_carrier, "Also band-pass the carrier before modulation");
        sub.add_flag("--no-refilter", o->no_refilter, "Do not band-pass the modulated carrier (not recommended)");
        sub.add_option("--low-noise-iterations", o->v.low_noise_iterations, "Iterations for the low-noise carrier")
            ->capture_default_str()->check(CLI::Range(0, 100));
        sub.add_option("--seed", o->v.seed, "Seed of the carrier noise and of the masking noise")->capture_default_str();
        sub.add_option("--noise", o->noise, "Masking noise: speech-shaped, or a noise WAV file");
        sub.add_option("--snr-db", o->snr_db, "Speech-to-noise ratio in dB (with --noise)")->capture_default_str();
        sub.add_option("--snr-reference", o->snr_reference,
                       "Speech level over the whole signal (whole) or over active 20 ms frames (active)")
            ->capture_default_str()
            ->check(one_of(snr_reference_names()));
        sub.add_option("--noise-stage", o->noise_stage, "Add the noise before or after vocoding")
            ->capture_default_str()
            ->check(one_of({"before", "after"}));
        sub.add_option("--ltas-from", o->ltas_from,
                       "WAV files or folders whose long-term spectrum shapes speech-shaped noise (default: the inputs)");
        sub.add_flag("--report", o->report, "Print every setting a methods section needs (band edges, filters, ...)");
        sub.add_option("--threads", o->threads, "Threads for --batch (0: all cores)")->capture_default_str();
        sub.add_option("--channels", o->channels,
                       "Several channels: mono (mixed down first, a note says so) or keep (each vocoded with the "
                       "same noise carrier, so a dual-mono input stays dual-mono)")
            ->capture_default_str()
            ->check(one_of(channel_mode_names()));
        return [o, &sub] { return run_vocode(*o, sub); };
    }});

}  // namespace
}  // namespace avsi::cli
