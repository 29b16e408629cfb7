// `avsi calibrate`: the vocoder band count and envelope cutoff whose mean
// ESTOI over a corpus folder is closest to a target (a pilot aid).
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/audio.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/vocoder/batch.h"
#include "avsi/vocoder/calibrate.h"
#include "ci_options.h"
#include "command.h"
#include "one_of.h"
#include "vocoder_choices.h"

namespace avsi::cli {
namespace {

using namespace avsi::vocoder;

struct CalibrateOptions {
    std::string corpus, out;
    CalibrationSettings c;
    std::string spacing = "greenwood", envelope = "rectify", carrier = "noise";
    bool stoi = false;
    CiOptionNames ci;
};

int run_calibrate(CalibrateOptions o) {
    o.c.base.spacing = parse_band_spacing(o.spacing, "--spacing");
    o.c.base.envelope = parse_envelope_method(o.envelope, "--envelope");
    o.c.base.carrier = parse_carrier_type(o.carrier, "--carrier");
    apply_ci_options(o.ci, o.c.base);
    o.c.extended = !o.stoi;
    std::vector<Audio> corpus;
    for (const auto& f : list_wav_files(o.corpus)) corpus.push_back(read_audio(f));
    const CalibrationResult result = calibrate(corpus, o.c);
    const std::string text = result.text();
    fmt::print("{}", text);
    if (!o.out.empty()) {
        write_text_file(o.out, text);
        log_info("wrote {}", o.out);
    }
    return 0;
}

const bool registered_calibrate = register_command({
    "calibrate",
    "Search vocoder band count and envelope cutoff for a target mean ESTOI over a corpus folder (pilot aid)",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<CalibrateOptions>();
        sub.add_option("--corpus", o->corpus, "Folder of clean speech WAV files")->required()->check(CLI::ExistingDirectory);
        sub.add_option("--target-estoi", o->c.target, "Target mean ESTOI (STOI with --stoi)")
            ->required()->check(CLI::Range(0.0, 1.0));
        sub.add_flag("--stoi", o->stoi, "Score with STOI instead of ESTOI");
        sub.add_option("--min-bands", o->c.min_bands, "Fewest bands searched")->capture_default_str()->check(CLI::Range(1, 64));
        sub.add_option("--max-bands", o->c.max_bands, "Most bands searched")->capture_default_str()->check(CLI::Range(1, 64));
        sub.add_option("--cutoffs-hz", o->c.cutoffs_hz, "Envelope cutoffs searched (Hz), comma-separated")
            ->delimiter(',')->capture_default_str();
        sub.add_option("--low-hz", o->c.base.low_hz, "Lower edge of the lowest band (Hz)")->capture_default_str();
        sub.add_option("--high-hz", o->c.base.high_hz, "Upper edge of the highest band (Hz)")->capture_default_str();
        sub.add_option("--spacing", o->spacing, "Band spacing: greenwood, log or linear")
            ->capture_default_str()
            ->check(one_of(band_spacing_names()));
        sub.add_option("--order", o->c.base.filter_order, "Butterworth prototype order of each band-pass")
            ->capture_default_str()->check(CLI::Range(1, 16));
        sub.add_option("--envelope", o->envelope, "Envelope: rectify, full-wave or hilbert")
            ->capture_default_str()
            ->check(one_of(envelope_method_names()));
        sub.add_option("--carrier", o->carrier, "Carrier: noise, sine, low-noise, pulse-train or poisson")
            ->capture_default_str()
            ->check(one_of(carrier_type_names()));
        add_ci_options(sub, o->c.base, o->ci);
        sub.add_option("--seed", o->c.base.seed, "Carrier noise seed")->capture_default_str();
        sub.add_option("--threads", o->c.threads, "Threads (0: all cores)")->capture_default_str();
        sub.add_option("--out", o->out, "Also write the table to this text file");
        return [o] { return run_calibrate(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
