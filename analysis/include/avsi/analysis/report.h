// `avsi analyze`: the repeated-measures ANOVA, sphericity, pairwise
// comparisons and descriptives of a scores.csv, written as a report folder:
//   index.html       self-contained page (inline CSS, plot as base64 PNG, no links)
//   report.md        the same in Markdown
//   anova.json       every number, full precision (the HTML shows these values)
//   pairwise.csv     all pairs: paired LSD, pooled LSD, Holm, Bonferroni, CI, d_z
//   descriptives.csv means, SDs and Cousineau-Morey within-subject CIs
//   plot.png, plot.svg  percent correct by condition with within-subject CIs
//   glmer.R          lme4::glmer(correct ~ condition + (1|subject) + (1|sentence))
//                    on keywords.csv, for those who want the keyword-level model
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/descriptives.h"
#include "avsi/analysis/pairwise.h"
#include "avsi/analysis/rm_anova.h"
#include "avsi/analysis/scores.h"

namespace avsi::analysis {

struct AnalysisResult {
    WithinData data;
    AnovaResult anova;
    std::vector<PairwiseComparison> pairwise;
    std::vector<ConditionSummary> descriptives;
};

// Runs the ANOVA, the pairwise comparisons and the descriptives.
AnalysisResult analyze(const WithinData& data, double confidence = 0.95);

// APA-style result line, e.g. "F(5, 120) = 9.13, p < .001, ηp² = .27".
std::string apa_anova(const AnovaResult& anova);
// APA p: "p = .032", "p < .001" (no leading zero).
std::string apa_p(double p);
// A p value for tables: 4 decimals, or scientific below 1e-4 ("2.50e-150").
std::string table_p(double p);

struct ReportSettings {
    std::filesystem::path out_dir;
    std::filesystem::path source;        // the scores.csv analysed (named in the report)
    std::filesystem::path keywords_csv;  // for glmer.R; empty: keywords.csv beside the source
    std::string title = "Keyword intelligibility by condition";
    double confidence = 0.95;
    std::string rule_set;  // keyword-scoring rule set of the scores ("" unknown), named in the report
    std::string dv = "percent";  // the dependent variable: its name labels the plot (percent: 0–100 %)
};

// The anova.json document (as text) for a result.
std::string anova_json(const AnalysisResult& result, const ReportSettings& settings);

// The report's Sphericity section: Mauchly's test, the Greenhouse-Geisser and
// Huynh-Feldt corrected dfs and p with their ε, as Markdown ("## Sphericity")
// or HTML; the SRT report prints the same section for its ANOVA.
std::string sphericity_markdown(const AnalysisResult& result);
std::string sphericity_html(const AnalysisResult& result);

// Writes every file of the report folder listed above.
void write_report(const AnalysisResult& result, const ReportSettings& settings);

struct AnalyzeSettings {
    std::filesystem::path input;  // scores.csv (an avsi SQLite database is refused with advice)
    std::filesystem::path out_dir;
    std::filesystem::path keywords_csv;
    double confidence = 0.95;
    std::string title = "Keyword intelligibility by condition";
    // The conditions to analyse, in report order (select_conditions); empty:
    // all, in their order in the file. `conditions_source` names where the
    // list came from in errors (an option or a protocol file).
    std::vector<std::string> conditions;
    std::string conditions_source = "--conditions";
    // The dependent variable's column (`avsi analyze --dv`): percent correct
    // by default, or any numeric column of a long-format table.
    std::string dv = "percent";
    // timing_certificate.csv from `avsi export` of online sessions: adds the
    // "Presentation timing" section; with exclude_timing_fail the subjects
    // whose timing failed are left out of the analysis (and named).
    std::filesystem::path timing_certificate;
    bool exclude_timing_fail = false;
    // The stimulus set the subjects saw (`avsi build-stimuli --out`): adds
    // its methods as "Stimuli and audio processing" (methods_report.h).
    std::filesystem::path stimuli_dir;
};

// The descriptive report of a dry run or pilot too small to test: fewer than
// 2 subjects with a score in every condition leave the ANOVA without an error
// term. Writes report.md, index.html and descriptives.csv (per condition:
// subjects, keywords scored, keywords correct, pooled percent correct) and
// says in each why there are no inferential statistics.
void write_pilot_report(const Scores& scores, const ReportSettings& settings, std::size_t complete_subjects);

// `avsi analyze`: reads the scores, analyses them and writes the report.
// With at least 2 conditions but fewer than 2 complete subjects (a one-subject
// dry run) it writes the pilot report instead, warns, and returns nullopt.
std::optional<AnalysisResult> analyze_file(const AnalyzeSettings& settings);

}  // namespace avsi::analysis
