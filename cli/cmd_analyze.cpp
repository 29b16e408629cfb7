// `avsi analyze`: repeated-measures ANOVA, sphericity, pairwise comparisons
// and the report folder from scores.csv.
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/analysis/adaptive_report.h"
#include "avsi/analysis/methods_report.h"
#include "avsi/analysis/phoneme_report.h"
#include "avsi/analysis/report.h"
#include "avsi/core/error.h"
#include "avsi/core/protocol.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct AnalyzeOptions {
    std::string input, out = "report", keywords, title = "Keyword intelligibility by condition", protocol;
    std::vector<std::string> conditions;
    double confidence = 0.95;
    std::string dv = "percent";
    bool include_unconverged = false;
    std::string timing_certificate;
    bool exclude_timing_fail = false;
    std::string phonemes, viseme_information, stimuli;
    std::size_t bootstrap = 2000;
};

const bool registered_analyze = register_command({
    "analyze",
    "Repeated-measures ANOVA, sphericity, pairwise LSD and an HTML/Markdown report from scores.csv",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<AnalyzeOptions>();
        sub.add_option("input", o->input,
                       "scores.csv from `avsi score` (a session database must go through `avsi export` and "
                       "`avsi score` first), or adaptive_trials.csv from `avsi export` (SRT analysis; needs --protocol)")
            ->required()
            ->check(CLI::ExistingFile);
        sub.add_option("--out", o->out, "Report folder")->capture_default_str();
        sub.add_option("--keywords", o->keywords,
                       "keywords.csv for the glmer.R script (default: keywords.csv beside the input)");
        sub.add_option("--confidence", o->confidence, "Confidence level of the intervals")
            ->capture_default_str()
            ->check(CLI::Range(0.5, 0.999));
        sub.add_option("--title", o->title, "Report title")->capture_default_str();
        sub.add_option("--dv", o->dv,
                       "Column of the dependent variable: percent (checked to lie in [0, 100]) or any numeric "
                       "column of a long-format subject,condition,<dv> table (a score, an SRT in dB)")
            ->capture_default_str();
        auto* conditions =
            sub.add_option("--conditions", o->conditions,
                           "Conditions to analyse, in the order of every table, plot and contrast, comma-separated "
                           "(default: all, in their order in the scores file)")
                ->delimiter(',');
        sub.add_option("--protocol", o->protocol,
                       "Take the conditions and their order from the [[condition]] tables of this protocol (as --conditions)")
            ->check(CLI::ExistingFile)
            ->excludes(conditions);
        sub.add_flag("--include-unconverged", o->include_unconverged,
                     "adaptive_trials.csv: keep tracks that hit a bound or did not reverse in the ANOVA and the "
                     "benefit (default: flagged, named and left out)");
        sub.add_option("--timing-certificate", o->timing_certificate,
                       "timing_certificate.csv from `avsi export` of online sessions: adds the per-participant "
                       "presentation timing to the report")
            ->check(CLI::ExistingFile);
        sub.add_flag("--exclude-timing-fail", o->exclude_timing_fail,
                     "Leave out the subjects whose presentation timing failed the tolerances (needs "
                     "--timing-certificate; they are named in the report)");
        sub.add_option("--phonemes", o->phonemes,
                       "phonemes.csv from `avsi score --phonemes`: adds \"What each model conveys\" (confusion heat "
                       "maps, information transmitted per feature with bootstrap CIs, glmer_phonemes.R)")
            ->check(CLI::ExistingFile);
        sub.add_option("--viseme-information", o->viseme_information,
                       "qc/viseme_information.csv of a stimulus set (build-stimuli writes it): each model's "
                       "objective viseme information beside the listeners' (with --phonemes)")
            ->check(CLI::ExistingFile);
        sub.add_option("--stimuli", o->stimuli,
                       "The stimulus set the subjects saw (the folder of `avsi build-stimuli --out`): adds its "
                       "methods (speech, models, every vocoder parameter) as \"Stimuli and audio processing\"")
            ->check(CLI::ExistingDirectory);
        sub.add_option("--bootstrap", o->bootstrap, "Subject-bootstrap replicates of the RTI intervals (with --phonemes)")
            ->capture_default_str()
            ->check(CLI::Range(std::size_t{0}, std::size_t{100000}));
        return [o, title = sub.get_option("--title"), dv = sub.get_option("--dv")] {
            if (analysis::is_adaptive_trials_file(o->input)) {
                if (dv->count() > 0)
                    throw UsageError("--dv: adaptive_trials.csv is analysed as SRTs in dB from its tracks; --dv is for "
                                     "a scores table");
                if (o->protocol.empty())
                    throw UsageError("--protocol: adaptive_trials.csv is analysed under the protocol's [adaptive] "
                                     "rules; give the protocol file");
                analysis::AdaptiveAnalyzeSettings a;
                a.input = o->input;
                a.protocol = o->protocol;
                a.out_dir = o->out;
                a.confidence = o->confidence;
                a.include_unconverged = o->include_unconverged;
                if (title->count() > 0) a.title = o->title;
                const auto result = analysis::analyze_adaptive_file(a);
                if (!o->stimuli.empty()) analysis::append_methods_section(a.out_dir, o->stimuli, result.conditions);
                if (result.excluded_tracks > 0)
                    fmt::print("{} of {} tracks did not converge ({}): {}\n", result.excluded_tracks,
                               result.tracks.size(), o->include_unconverged ? "kept" : "left out",
                               fmt::join(result.excluded, "; "));
                if (result.anova) fmt::print("SRT ({}): {}\n", result.scale, analysis::apa_anova(result.anova->anova));
                for (const auto& b : result.benefits)
                    if (b.n >= 2)
                        fmt::print("visual benefit of {} over {}: {:.2f} {}, {:.0f} % CI [{:.2f}, {:.2f}] (n = {})\n",
                                   b.condition, b.reference, b.mean_db, result.scale, 100 * a.confidence, b.ci_low_db,
                                   b.ci_high_db, b.n);
                    else
                        fmt::print("visual benefit of {} over {}: {:.2f} {} (n = {}: no interval)\n", b.condition,
                                   b.reference, b.mean_db, result.scale, b.n);
                fmt::print("report: {}\n", (a.out_dir / "index.html").string());
                return 0;
            }
            analysis::AnalyzeSettings s;
            s.input = o->input;
            s.out_dir = o->out;
            s.keywords_csv = o->keywords;
            s.confidence = o->confidence;
            s.title = o->title;
            s.dv = o->dv;
            s.conditions = o->conditions;
            s.timing_certificate = o->timing_certificate;
            s.exclude_timing_fail = o->exclude_timing_fail;
            s.stimuli_dir = o->stimuli;
            if (!o->protocol.empty()) {
                for (const auto& c : load_protocol(o->protocol).conditions) s.conditions.push_back(c.name);
                s.conditions_source = o->protocol;
            }
            if (!o->viseme_information.empty() && o->phonemes.empty())
                throw UsageError("--viseme-information is shown beside the listeners' RTI: add --phonemes");
            const auto result = analysis::analyze_file(s);
            if (!o->phonemes.empty()) {
                analysis::PhonemeReportSettings p;
                p.phonemes_csv = o->phonemes;
                p.out_dir = s.out_dir;
                p.bootstrap = o->bootstrap;
                p.conditions = s.conditions;
                p.objective_csv = o->viseme_information;
                analysis::append_phoneme_section(p);
            }
            if (result)
                fmt::print("{}\n", analysis::apa_anova(result->anova));
            else
                fmt::print("pilot report (too few subjects for an ANOVA): {}\n", (s.out_dir / "report.md").string());
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
