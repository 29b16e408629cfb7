// Subject × condition scores (percent of keywords correct) and the complete
// within-subject data matrix the ANOVA works on.
//
//   scores.csv: subject,condition,keywords,correct,percent[,rule_set]   (long format)
//
// or any long-format table with a numeric dependent variable in a column of
// its own (`subject,condition,score`, speech reception thresholds in dB):
// read_scores(path, "score"). Only `percent` is checked against [0, 100].
//
// Conditions keep the order in which they first appear in the file, so every
// table, plot and contrast ("b - a") follows the order the user gave.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace avsi::analysis {

// One subject × condition cell.
struct ScoreCell {
    std::string subject;
    std::string condition;
    int keywords = 0;          // keywords scored (0 when only percent is known)
    int correct = 0;           // keywords correct
    std::optional<double> percent;  // the dependent variable (percent correct by default); nullopt = missing ("NA" or empty)
};

struct Scores {
    std::vector<ScoreCell> cells;
    // The keyword-scoring rule set that produced them ("strict", "loose",
    // "lenient"; scoring.h), "" when not known (a scores file from elsewhere).
    std::string rule_set;
    // The column the values came from ("percent", or any --dv column).
    std::string dv = "percent";
};

// Reads scores.csv. Requires columns subject, condition and the dependent
// variable `dv` (default percent); keywords, correct and rule_set (the same on
// every row) are optional. "NA" or an empty value is a missing cell. Duplicate
// subject × condition rows, values that are not numbers and, for percent
// only, values outside [0, 100] are errors naming file:line:column.
Scores read_scores(const std::filesystem::path& path, const std::string& dv = "percent");

// The cells of `conditions` only, grouped in that order (file order within a
// condition), so every table, plot and contrast follows it. An empty list
// keeps `scores` as they are. A listed condition the scores do not have, or
// one listed twice, is an InputError naming `source` (field "conditions"),
// with the conditions present (and "did you mean").
Scores select_conditions(const Scores& scores, const std::vector<std::string>& conditions,
                         const std::string& source);

// Writes scores.csv (atomically), percent with full precision.
void write_scores(const std::filesystem::path& path, const Scores& scores);

// A complete subjects × conditions matrix (row-major) after listwise deletion.
struct WithinData {
    std::vector<std::string> subjects;
    std::vector<std::string> conditions;
    std::vector<double> values;  // values[i * conditions.size() + j]
    // Subjects dropped because a cell was missing, with the missing conditions.
    struct Dropped {
        std::string subject;
        std::vector<std::string> missing_conditions;
    };
    std::vector<Dropped> dropped;

    std::size_t n() const { return subjects.size(); }
    std::size_t k() const { return conditions.size(); }
    double at(std::size_t subject, std::size_t condition) const {
        return values[subject * conditions.size() + condition];
    }
};

// Builds the complete matrix: conditions and subjects in first-appearance
// order; a subject missing any condition is dropped listwise and named through
// avsi::log_warning. Throws InputError (naming `source`) if fewer than 2
// conditions or 2 complete subjects remain.
WithinData make_within_data(const Scores& scores, const std::string& source = "scores");

// Builds WithinData directly from a complete matrix (for simulations and tests).
WithinData make_within_data(std::vector<std::string> subjects, std::vector<std::string> conditions,
                            std::vector<double> values);

}  // namespace avsi::analysis
