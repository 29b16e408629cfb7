// `avsi analyze`: repeated-measures ANOVA, sphericity, pairwise comparisons
// and the report folder from scores.csv.
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/analysis/report.h"
#include "avsi/core/protocol.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct AnalyzeOptions {
    std::string input, out = "report", keywords, title = "Keyword intelligibility by condition", protocol;
    std::vector<std::string> conditions;
    double confidence = 0.95;
    std::string dv = "percent";
};

const bool registered_analyze = register_command({
    "analyze",
    "Repeated-measures ANOVA, sphericity, pairwise LSD and an HTML/Markdown report from scores.csv",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<AnalyzeOptions>();
        sub.add_option("input", o->input,
                       "scores.csv from `avsi score` (a session database must go through `avsi export` and "
                       "`avsi score` first)")
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
        return [o] {
            analysis::AnalyzeSettings s;
            s.input = o->input;
            s.out_dir = o->out;
            s.keywords_csv = o->keywords;
            s.confidence = o->confidence;
            s.title = o->title;
            s.dv = o->dv;
            s.conditions = o->conditions;
            if (!o->protocol.empty()) {
                for (const auto& c : load_protocol(o->protocol).conditions) s.conditions.push_back(c.name);
                s.conditions_source = o->protocol;
            }
            const auto result = analysis::analyze_file(s);
            if (result)
                fmt::print("{}\n", analysis::apa_anova(result->anova));
            else
                fmt::print("pilot report (too few subjects for an ANOVA): {}\n", (s.out_dir / "report.md").string());
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
