// `avsi corpus fit-markers LIST.csv --out DIR`: optical motion-capture
// recordings (C3D, Qualisys TSV, Motive CSV) fitted to a head — the built-in
// one with protocols/head/markers.json, or a lab's OBJ + rig or glTF head
// with its own layout — and written as a parameter-track corpus for `avsi
// train` and `avsi evaluate`, with the fit's residual report
// (learn/marker_corpus.h). An action of `avsi corpus` (cmd_corpus.cpp).
#include <functional>
#include <memory>
#include <string>

#include "avsi/core/log.h"
#include "avsi/learn/marker_corpus.h"
#include "avsi/stimuli/commands.h"
#include "avsi/stimuli/marker_layout.h"
#include "command.h"
#include "head_options.h"

namespace avsi::cli {
namespace {

struct FitMarkersOptions {
    learn::MarkerCorpusSettings settings;
    stimuli::HeadFiles head;
    std::string layout = stimuli::default_marker_layout().string();
    long long reference_frame = -1;
};

int run_fit_markers(FitMarkersOptions& o) {
    const stimuli::Head head = stimuli::load_head_files(o.head);
    const synth::MarkerModel model = stimuli::load_marker_model(head, o.layout);
    if (o.reference_frame >= 0) o.settings.fit.reference_frame = static_cast<std::size_t>(o.reference_frame);
    o.settings.head_name = o.head.gltf.empty() ? o.head.obj.string() : o.head.gltf.string();
    const learn::MarkerCorpusSummary s = learn::fit_marker_corpus(o.settings, model);
    log_info("fitted {} recordings, {} of {} frames; residual RMS {:.2f} mm; wrote {} (report: fit/report.md)",
             s.recordings, s.frames_fitted, s.frames, s.residual_rms_mm, o.settings.out_dir.string());
    return 0;
}

void add_fit_markers(CLI::App& corpus, std::function<int()>& chosen) {
    auto o = std::make_shared<FitMarkersOptions>();
    CLI::App* sub = corpus.add_subcommand(
        "fit-markers", "Fit optical motion capture (C3D, Qualisys TSV, Motive CSV) to a head: a parameter-track "
                       "corpus with a residual report");
    sub->add_option("list", o->settings.list_path, "Recording list CSV: id, markers, labels[, audio][, split]")
        ->required();
    sub->add_option("--out", o->settings.out_dir, "Corpus folder to write (corpus.json, tracks/, labels/, fit/)")
        ->required();
    add_head_options(*sub, o->head);
    sub->add_option("--layout", o->layout, "Marker layout on the head (JSON)")->capture_default_str();
    sub->add_option("--name", o->settings.name, "Corpus name in the manifest")->capture_default_str();
    sub->add_option("--reference-frame", o->reference_frame,
                    "Frame of the reference pose (relaxed face, jaw and lips closed); default: the first frame "
                    "showing every reference and strategic marker");
    sub->add_option("--threads", o->settings.fit.threads, "Fitting threads (0: the hardware's)")->capture_default_str();
    sub->add_option("--split-seed", o->settings.split_seed, "Seed of the train/test split")->capture_default_str();
    sub->add_option("--test-fraction", o->settings.test_fraction, "Fraction of recordings in the test split")
        ->capture_default_str();
    sub->callback([o, &chosen] { chosen = [o] { return run_fit_markers(*o); }; });
}

const bool registered_fit_markers = register_action("corpus", add_fit_markers);

}  // namespace
}  // namespace avsi::cli
