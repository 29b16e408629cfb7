// `avsi import-web`: online results (JATOS exports, jsPsych JSON) into the
// session database, validated against the design.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/experiment/web_study.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct ImportWebOptions {
    std::vector<std::string> results;
    std::string protocol;
    std::string db;
    std::string stimuli;
};

int run_import_web(const ImportWebOptions& o) {
    if (o.protocol.empty()) throw UsageError("--protocol is required (the protocol the study was exported from)");
    if (o.db.empty()) throw UsageError("--db is required (the session database; created if missing)");
    experiment::ImportWebSettings s;
    for (const auto& r : o.results) s.results.emplace_back(r);
    s.protocol = o.protocol;
    s.database = o.db;
    s.stimuli = o.stimuli;
    const auto r = experiment::import_web(s);
    for (const auto& note : r.notes) log_info("import-web: {}", note);
    if (r.ignored > 0) log_info("import-web: {} JSON objects that are not avsi records were skipped", r.ignored);
    if (r.duplicates > 0) log_info("import-web: {} trial records were read twice and counted once", r.duplicates);
    if (r.screening_failed > 0)
        log_warning("import-web: {} headphone check(s) failed; the subjects are imported with their results in "
                    "screening.csv (`avsi export`): decide on exclusions before `avsi analyze`",
                    r.screening_failed);
    log_info("import-web: {} records, {} subjects ({} new), {} browser sessions added, {} trials added, {} already "
             "stored; database {}",
             r.records, r.subjects, r.subjects_added, r.sessions_added, r.trials_added, r.trials_present, o.db);
    return 0;
}

const bool registered_import_web = register_command({
    "import-web",
    "Import online results (JATOS export or jsPsych JSON) into the session database, checked against the design",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<ImportWebOptions>();
        sub.add_option("results", o->results,
                       "Results files: JATOS \"data only\" export (.txt), JATOS results archive (.jrzip/.zip), "
                       "jsPsych JSON, or the study's own download/POST lines")
            ->required()
            ->check(CLI::ExistingFile);
        sub.add_option("--protocol", o->protocol, "Protocol file the study was exported from")->check(CLI::ExistingFile);
        sub.add_option("--db", o->db, "Session database (the lab runner's; created if missing)");
        sub.add_option("--stimuli", o->stimuli,
                       "Folder with the manifest.json the study was exported from (the stimulus folder, or the "
                       "exported study folder); stimulus hashes are checked against it")
            ->required()
            ->check(CLI::ExistingDirectory);
        return [o] { return run_import_web(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
