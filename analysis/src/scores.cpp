// scores.csv reading/writing and listwise deletion into a complete matrix.
#include "avsi/analysis/scores.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"

namespace avsi::analysis {

namespace {

bool is_missing(const std::string& s) { return s.empty() || s == "NA" || s == "na" || s == "NaN"; }

}  // namespace

Scores read_scores(const std::filesystem::path& path, const std::string& dv) {
    const CsvTable table = read_csv(path);
    const std::string p = path.string();
    const std::size_t c_subject = table.require_column("subject");
    const std::size_t c_condition = table.require_column("condition");
    const std::size_t c_percent = table.require_column(dv);
    const bool percent_dv = dv == "percent";
    const auto c_keywords = table.column("keywords");
    const auto c_correct = table.column("correct");
    const auto c_rule_set = table.column("rule_set");

    Scores scores;
    scores.dv = dv;
    DiagnosticList problems;
    std::set<std::pair<std::string, std::string>> seen;
    for (const auto& row : table.rows) {
        ScoreCell cell;
        cell.subject = trim(row.fields[c_subject]);
        cell.condition = trim(row.fields[c_condition]);
        if (cell.subject.empty())
            problems.add(p, row.line, int(c_subject) + 1, "subject", "expected a subject id, got an empty field");
        if (cell.condition.empty())
            problems.add(p, row.line, int(c_condition) + 1, "condition",
                         "expected a condition name, got an empty field");
        const std::string percent = trim(row.fields[c_percent]);
        if (!is_missing(percent)) {
            const auto v = parse_double(percent);
            if (percent_dv && (!v || *v < 0.0 || *v > 100.0))
                problems.add(p, row.line, int(c_percent) + 1, "percent",
                             fmt::format("expected a number in [0, 100] or NA, got \"{}\"", percent));
            else if (!v || !std::isfinite(*v))
                problems.add(p, row.line, int(c_percent) + 1, dv,
                             fmt::format("expected a number or NA, got \"{}\"", percent));
            else
                cell.percent = *v;
        }
        auto read_count = [&](std::optional<std::size_t> column, const char* name, int& out) {
            if (!column) return;
            const std::string text = trim(row.fields[*column]);
            if (is_missing(text)) return;
            const auto v = parse_int(text);
            if (!v || *v < 0)
                problems.add(p, row.line, int(*column) + 1, name,
                             fmt::format("expected a non-negative integer, got \"{}\"", text));
            else
                out = int(*v);
        };
        read_count(c_keywords, "keywords", cell.keywords);
        read_count(c_correct, "correct", cell.correct);
        if (cell.correct > cell.keywords && c_keywords && c_correct && cell.keywords > 0)
            problems.add(p, row.line, 0, "correct",
                         fmt::format("expected at most keywords = {}, got {}", cell.keywords, cell.correct));
        if (c_rule_set) {
            const std::string set = trim(row.fields[*c_rule_set]);
            if (scores.rule_set.empty() && !set.empty()) scores.rule_set = set;
            else if (set != scores.rule_set)
                problems.add(p, row.line, int(*c_rule_set) + 1, "rule_set",
                             fmt::format("expected the rule set of the rows before (\"{}\"): one scores file "
                                         "holds one scoring, got \"{}\"",
                                         scores.rule_set, set));
        }
        if (!seen.insert({cell.subject, cell.condition}).second)
            problems.add(p, row.line, 0, "subject,condition",
                         fmt::format("duplicate row for subject '{}' in condition '{}'", cell.subject,
                                     cell.condition));
        scores.cells.push_back(std::move(cell));
    }
    if (table.rows.empty()) problems.add(p, 0, 0, "", "expected at least one score row, got none");
    problems.throw_if_any();
    return scores;
}

Scores select_conditions(const Scores& scores, const std::vector<std::string>& conditions,
                         const std::string& source) {
    if (conditions.empty()) return scores;
    std::vector<std::string> present;
    for (const auto& c : scores.cells)
        if (std::find(present.begin(), present.end(), c.condition) == present.end()) present.push_back(c.condition);
    DiagnosticList problems;
    std::set<std::string> listed;
    for (const auto& name : conditions) {
        if (!listed.insert(name).second) {
            problems.add(source, 0, 0, "conditions", fmt::format("condition '{}' is listed twice", name));
        } else if (std::find(present.begin(), present.end(), name) == present.end()) {
            const std::string near = closest_match(name, present);
            problems.add(source, 0, 0, "conditions",
                         fmt::format("expected one of the conditions in the scores ({}), got '{}'{}",
                                     fmt::join(present, ", "), name,
                                     near.empty() ? "" : fmt::format(" (did you mean '{}'?)", near)));
        }
    }
    problems.throw_if_any();
    Scores selected;
    selected.rule_set = scores.rule_set;
    selected.dv = scores.dv;
    for (const auto& name : conditions)
        for (const auto& c : scores.cells)
            if (c.condition == name) selected.cells.push_back(c);
    return selected;
}

void write_scores(const std::filesystem::path& path, const Scores& scores) {
    std::vector<std::string> header = {"subject", "condition", "keywords", "correct", "percent"};
    if (!scores.rule_set.empty()) header.push_back("rule_set");
    std::string out = csv_line(header);
    for (const auto& c : scores.cells) {
        std::vector<std::string> fields = {c.subject, c.condition, std::to_string(c.keywords),
                                           std::to_string(c.correct),
                                           c.percent ? fmt::format("{}", *c.percent) : std::string("NA")};
        if (!scores.rule_set.empty()) fields.push_back(scores.rule_set);
        out += csv_line(fields);
    }
    write_text_file(path, out);
}

WithinData make_within_data(const Scores& scores, const std::string& source) {
    std::vector<std::string> subjects, conditions;
    std::map<std::string, std::size_t> subject_index, condition_index;
    for (const auto& c : scores.cells) {
        if (subject_index.emplace(c.subject, subjects.size()).second) subjects.push_back(c.subject);
        if (condition_index.emplace(c.condition, conditions.size()).second) conditions.push_back(c.condition);
    }
    const std::size_t k = conditions.size();
    std::vector<std::vector<std::optional<double>>> cell(subjects.size(),
                                                         std::vector<std::optional<double>>(k));
    for (const auto& c : scores.cells) cell[subject_index[c.subject]][condition_index[c.condition]] = c.percent;

    WithinData data;
    data.conditions = conditions;
    for (std::size_t i = 0; i < subjects.size(); ++i) {
        std::vector<std::string> missing;
        for (std::size_t j = 0; j < k; ++j)
            if (!cell[i][j]) missing.push_back(conditions[j]);
        if (!missing.empty()) {
            log_warning("{}: subject '{}' dropped from the analysis (listwise): no score in condition{} {}",
                        source, subjects[i], missing.size() > 1 ? "s" : "", fmt::join(missing, ", "));
            data.dropped.push_back({subjects[i], missing});
            continue;
        }
        data.subjects.push_back(subjects[i]);
        for (std::size_t j = 0; j < k; ++j) data.values.push_back(*cell[i][j]);
    }
    if (k < 2)
        throw InputError(source, 0, 0, "condition",
                         fmt::format("expected at least 2 conditions for a repeated-measures analysis, got {}", k));
    if (data.subjects.size() < 2)
        throw InputError(source, 0, 0, "subject",
                         fmt::format("expected at least 2 subjects with a score in every condition, got {} "
                                     "({} dropped for missing cells)",
                                     data.subjects.size(), data.dropped.size()));
    return data;
}

WithinData make_within_data(std::vector<std::string> subjects, std::vector<std::string> conditions,
                            std::vector<double> values) {
    AVSI_ASSERT(values.size() == subjects.size() * conditions.size());
    WithinData data;
    data.subjects = std::move(subjects);
    data.conditions = std::move(conditions);
    data.values = std::move(values);
    return data;
}

}  // namespace avsi::analysis
