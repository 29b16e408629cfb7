// `avsi export-web`: the protocol's lists and stimuli as a jsPsych study
// folder and a JATOS study archive (.jzip).
#include <filesystem>
#include <memory>
#include <string>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/experiment/web_study.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct ExportWebOptions {
    std::string protocol;
    std::string stimuli;
    std::string lists;
    std::string out;
    std::string jzip;
    std::string web_dir;
};

int run_export_web(const ExportWebOptions& o) {
    if (o.stimuli.empty()) throw UsageError("--stimuli is required (the folder built by `avsi build-stimuli`)");
    if (o.lists.empty()) throw UsageError("--lists is required (lists.csv from `avsi design`)");
    if (o.out.empty()) throw UsageError("--out is required (the study folder to write)");
    experiment::ExportWebSettings s;
    s.protocol = o.protocol;
    s.stimuli_dir = o.stimuli;
    s.lists = o.lists;
    s.out_dir = o.out;
    s.jzip = o.jzip;
    s.web_dir = o.web_dir;
    const auto r = experiment::export_web(s);
    log_info("export-web: study {} for {} subjects ({} trials), {} stimuli ({} transcoded) in {}", r.study_id,
             r.subjects, r.trials, r.stimuli, r.transcoded, o.out);
    log_info("export-web: JATOS study archive {} (import it in JATOS: Studies → Import study)", r.jzip.string());
    return 0;
}

const bool registered_export_web = register_command({
    "export-web",
    "Export the protocol's lists and stimuli as a jsPsych study folder and a JATOS study archive (.jzip)",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<ExportWebOptions>();
        sub.add_option("protocol", o->protocol, "Protocol file (TOML); its [online] section configures the study")
            ->required()
            ->check(CLI::ExistingFile);
        sub.add_option("--stimuli", o->stimuli,
                       "Stimulus folder built by `avsi build-stimuli` (every clip is checked against manifest.json; "
                       "clips browsers cannot play are transcoded to H.264 Constrained Baseline + AAC)");
        sub.add_option("--lists", o->lists,
                       "lists.csv from `avsi design` (the subjects the study serves; each is checked against the "
                       "protocol's design)");
        sub.add_option("--out", o->out, "Study folder to write (runs from any static web server: index.html)");
        sub.add_option("--jzip", o->jzip, "JATOS study archive to write (default: <out>.jzip)");
        sub.add_option("--web-dir", o->web_dir,
                       "avsi's web/ folder with src/ and node_modules/ (default: the source tree's, installed by "
                       "scripts/install-deps)");
        return [o] { return run_export_web(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
