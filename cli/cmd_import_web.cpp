// `avsi import-web`: online results (JATOS exports, jsPsych JSON) into the
// session database, validated against the design.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

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
    std::string runs;
    bool require_complete = false;
};

int run_import_web(const ImportWebOptions& o) {
    if (o.protocol.empty()) throw UsageError("--protocol is required (the protocol the study was exported from)");
    if (o.db.empty()) throw UsageError("--db is required (the session database; created if missing)");
    experiment::ImportWebSettings s;
    for (const auto& r : o.results) s.results.emplace_back(r);
    s.protocol = o.protocol;
    s.database = o.db;
    s.stimuli = o.stimuli;
    if (!o.runs.empty()) s.runs = experiment::parse_run_choice(o.runs);
    s.require_complete = o.require_complete;
    const auto r = experiment::import_web(s);
    for (const auto& note : r.notes) log_info("import-web: {}", note);
    for (const auto& left : r.left_out) {
        std::string sessions;
        for (const auto& id : left.sessions) sessions += (sessions.empty() ? "" : ",") + id;
        log_warning("import-web: subject {}: run {} left out (started {}, {} trials, sessions {}); kept run {} ({} "
                    "trials) by --runs {}",
                    left.subject, left.run, left.started_utc, left.trials, sessions.empty() ? "none" : sessions,
                    left.kept_run, left.kept_trials, o.runs);
    }
    if (!r.incomplete.empty()) {
        std::string list;
        for (const auto& i : r.incomplete)
            list += fmt::format("{}subject {} ({} of {})", list.empty() ? "" : ", ", i.subject, i.answered, i.planned);
        log_warning("import-web: {} subject(s) with fewer trials than the design: {} (--require-complete refuses them)",
                    r.incomplete.size(), list);
    }
    if (r.ignored > 0) log_info("import-web: {} JSON objects that are not avsi records were skipped", r.ignored);
    if (r.duplicates > 0) log_info("import-web: {} trial records were read twice and counted once", r.duplicates);
    if (r.screening_failed > 0)
        log_warning("import-web: {} headphone check(s) failed; the subjects are imported with their results in "
                    "screening.csv (`avsi export`): decide on exclusions before `avsi analyze`",
                    r.screening_failed);
    for (const auto& c : r.timing) {
        if (c.verdict == experiment::TimingVerdict::Pass) log_info("import-web: {}", experiment::describe(c));
        else log_warning("import-web: {}", experiment::describe(c));
    }
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
        sub.add_option("--runs", o->runs,
                       "A subject who took the study in several browsers: keep the first, last, most-complete run, "
                       "or session=ID[,ID...] (the run holding that browser session); the others are reported. "
                       "Without it such a subject is an error");
        sub.add_flag("--require-complete", o->require_complete,
                     "Refuse the import when a subject has fewer trials than the design");
        return [o] { return run_import_web(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
