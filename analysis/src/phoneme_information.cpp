// Confusion matrices and information transmitted per feature
// (phoneme_information.h: the equations, the groupings and the bootstrap).
#include "avsi/analysis/phoneme_information.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

#include "avsi/analysis/pairwise.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/rng.h"
#include "avsi/core/sentence_profile.h"

namespace avsi::analysis {
namespace {

constexpr const char* k_deleted = "-";
constexpr const char* k_other = "other";

float feature(const PhoneInfo& p, Feature f) { return p.features[static_cast<std::size_t>(f)]; }
bool is_vowel(const PhoneInfo& p) { return p.phone_class == PhoneClass::Vowel; }

std::string manner_of(const PhoneInfo& p) {
    if (feature(p, Feature::Nasal) > 0.5f) return "nasal";
    const bool stop = feature(p, Feature::Stop) > 0.5f, fricative = feature(p, Feature::Fricative) > 0.5f;
    if (stop && fricative) return "affricate";
    if (stop) return "stop";
    if (fricative) return "fricative";
    return "approximant";
}

std::string place_of(const PhoneInfo& p) {
    const bool bilabial = feature(p, Feature::Bilabial) > 0.5f, velar = feature(p, Feature::Velar) > 0.5f;
    if (bilabial && velar) return "labial-velar";
    if (bilabial) return "bilabial";
    if (feature(p, Feature::Labiodental) > 0.5f) return "labiodental";
    if (feature(p, Feature::Dental) > 0.5f) return "dental";
    if (feature(p, Feature::Alveolar) > 0.5f) return "alveolar";
    if (feature(p, Feature::Retroflex) > 0.5f) return "retroflex";
    if (velar) return "velar";
    return "other place";
}

bool rounded(const PhoneInfo& p) {
    return feature(p, Feature::Rounded) >= 0.5f || feature(p, Feature::Protruded) >= 0.5f;
}

// The target (response) category of a row under a grouping; nullopt when
// the grouping does not classify the row's target.
std::optional<std::string> category_of_row(const std::string& grouping, const PhonemeRow& row, bool response) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    if (!response) {
        const std::string c = feature_category(grouping, inventory.info(row.target), false);
        return c.empty() ? std::nullopt : std::optional<std::string>(c);
    }
    if (row.response.empty()) return std::string(k_deleted);
    return feature_category(grouping, inventory.info(row.response), true);
}

// Sorted list of the categories a set holds, "-" and "other" last.
std::vector<std::string> ordered(const std::set<std::string>& categories) {
    std::vector<std::string> out, tail;
    for (const auto& c : categories) (c == k_deleted || c == k_other ? tail : out).push_back(c);
    std::sort(tail.begin(), tail.end(),
              [](const std::string& a, const std::string& b) { return a == k_other && b != k_other; });
    out.insert(out.end(), tail.begin(), tail.end());
    return out;
}

// A matrix over the given categories from (target, response) pairs.
ConfusionMatrix matrix_of(const std::string& condition, const std::string& kind,
                          const std::vector<std::pair<std::string, std::string>>& pairs, std::vector<std::string> rows,
                          std::vector<std::string> columns) {
    ConfusionMatrix m{condition, kind, std::move(rows), std::move(columns), {}};
    m.counts.assign(m.rows.size(), std::vector<double>(m.columns.size(), 0.0));
    std::map<std::string, std::size_t> r, c;
    for (std::size_t i = 0; i < m.rows.size(); ++i) r[m.rows[i]] = i;
    for (std::size_t j = 0; j < m.columns.size(); ++j) c[m.columns[j]] = j;
    for (const auto& [t, y] : pairs) m.counts[r.at(t)][c.at(y)] += 1.0;
    return m;
}

// The language the rows' phones are of: the first of English and then the
// other tables (sorted) whose phones hold every target and response. One
// front end transcribes a study's answers, so its language holds them all.
std::string language_of_rows(const std::vector<PhonemeRow>& rows) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::vector<std::string> codes = {"en"};
    for (const auto& code : inventory.languages())
        if (code != "en") codes.push_back(code);
    for (const auto& code : codes) {
        const auto& phones = inventory.language_phones(code);
        const auto holds = [&](const std::string& symbol) {
            return symbol.empty() || std::find(phones.begin(), phones.end(), symbol) != phones.end();
        };
        if (std::all_of(rows.begin(), rows.end(),
                        [&](const PhonemeRow& r) { return holds(r.target) && holds(r.response); }))
            return code;
    }
    throw InputError("phonemes", 0, 0, "target",
                     "the phones of these answers are of no one language table (protocols/languages/)");
}

// The phone matrix of consonant (vowel) targets: every phone of that class
// in `language` as a row and a column, then "other" and "-".
ConfusionMatrix phone_matrix(const std::string& condition, const std::vector<PhonemeRow>& rows, bool vowels,
                             const std::string& language) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::vector<std::pair<std::string, std::string>> pairs;
    for (const auto& row : rows) {
        if (row.target.empty() || is_vowel(inventory.info(row.target)) != vowels) continue;
        std::string y = row.response.empty()                               ? k_deleted
                        : is_vowel(inventory.info(row.response)) == vowels ? row.response
                                                                           : k_other;
        pairs.emplace_back(row.target, std::move(y));
    }
    std::vector<std::string> symbols;
    for (const auto& symbol : inventory.language_phones(language)) {
        const PhoneInfo& p = inventory.info(symbol);
        if (p.phone_class != PhoneClass::Silence && is_vowel(p) == vowels) symbols.push_back(p.symbol);
    }
    std::vector<std::string> columns = symbols;
    columns.emplace_back(k_other);
    columns.emplace_back(k_deleted);
    return matrix_of(condition, vowels ? "vowels" : "consonants", pairs, symbols, columns);
}

// Counts per (subject, grouping) of one condition, over the categories of the whole data.
struct GroupingTables {
    std::vector<std::string> x_categories, y_categories;
    std::map<std::string, std::vector<std::vector<double>>> by_subject;  // subject -> counts
};

std::vector<std::vector<double>> sum_tables(const std::vector<const std::vector<std::vector<double>>*>& tables,
                                            std::size_t rows, std::size_t columns) {
    std::vector<std::vector<double>> out(rows, std::vector<double>(columns, 0.0));
    for (const auto* t : tables)
        for (std::size_t i = 0; i < rows; ++i)
            for (std::size_t j = 0; j < columns; ++j) out[i][j] += (*t)[i][j];
    return out;
}

double percentile(std::vector<double> v, double q) {
    v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    // R's quantile type 7.
    const double h = (double(v.size()) - 1.0) * q;
    const auto lo = static_cast<std::size_t>(std::floor(h));
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (h - double(lo)) * (v[hi] - v[lo]);
}

// The tables of every condition for one grouping, with categories shared by all conditions.
std::map<std::string, GroupingTables> grouping_tables(const std::string& grouping,
                                                      const std::vector<PhonemeRow>& rows) {
    std::set<std::string> xs, ys;
    for (const auto& row : rows) {
        if (row.outcome == PhoneOutcome::Inserted) continue;
        const auto x = category_of_row(grouping, row, false);
        if (!x) continue;
        xs.insert(*x);
        ys.insert(*category_of_row(grouping, row, true));
    }
    std::map<std::string, GroupingTables> out;
    const std::vector<std::string> x_list = ordered(xs), y_list = ordered(ys);
    std::map<std::string, std::size_t> xi, yi;
    for (std::size_t i = 0; i < x_list.size(); ++i) xi[x_list[i]] = i;
    for (std::size_t j = 0; j < y_list.size(); ++j) yi[y_list[j]] = j;
    for (const auto& row : rows) {
        if (row.outcome == PhoneOutcome::Inserted) continue;
        const auto x = category_of_row(grouping, row, false);
        if (!x) continue;
        GroupingTables& g = out[row.condition];
        if (g.x_categories.empty()) {
            g.x_categories = x_list;
            g.y_categories = y_list;
        }
        auto& t = g.by_subject[row.subject];
        if (t.empty()) t.assign(x_list.size(), std::vector<double>(y_list.size(), 0.0));
        t[xi.at(*x)][yi.at(*category_of_row(grouping, row, true))] += 1.0;
    }
    return out;
}

std::vector<std::string> conditions_in_order(const std::vector<PhonemeRow>& rows) {
    std::vector<std::string> out;
    for (const auto& r : rows)
        if (std::find(out.begin(), out.end(), r.condition) == out.end()) out.push_back(r.condition);
    return out;
}

std::vector<std::string> subjects_in_order(const std::vector<PhonemeRow>& rows) {
    std::vector<std::string> out;
    std::set<std::string> seen;
    for (const auto& r : rows)
        if (seen.insert(r.subject).second) out.push_back(r.subject);
    return out;
}

// RTI of one condition's pooled tables of the drawn subjects (NaN if none).
double rti_of_draw(const GroupingTables& g, const std::vector<const std::string*>& draw) {
    std::vector<const std::vector<std::vector<double>>*> tables;
    for (const auto* s : draw)
        if (auto it = g.by_subject.find(*s); it != g.by_subject.end()) tables.push_back(&it->second);
    if (tables.empty()) return std::numeric_limits<double>::quiet_NaN();
    const Transmission t = information_transmitted(sum_tables(tables, g.x_categories.size(), g.y_categories.size()));
    return t.h_x_corrected > 0.0 ? t.rti : std::numeric_limits<double>::quiet_NaN();
}

// One grouping: the rows (with CIs) and the paired comparisons.
void information_of_grouping(const std::string& grouping, const std::vector<PhonemeRow>& rows,
                             const InformationSettings& settings, InformationResult& out) {
    const auto tables = grouping_tables(grouping, rows);
    const auto conditions = conditions_in_order(rows);
    const auto subjects = subjects_in_order(rows);
    std::vector<std::string> present;
    for (const auto& c : conditions)
        if (tables.count(c)) present.push_back(c);
    // Bootstrap: the same drawn subjects for every condition (paired).
    std::map<std::string, std::vector<double>> draws;
    Rng rng = Rng(settings.seed).derive("phoneme-information/" + grouping);
    for (std::size_t b = 0; b < settings.bootstrap; ++b) {
        std::vector<const std::string*> draw;
        for (std::size_t k = 0; k < subjects.size(); ++k) draw.push_back(&subjects[rng.uniform_int(subjects.size())]);
        for (const auto& c : present) draws[c].push_back(rti_of_draw(tables.at(c), draw));
    }
    for (const auto& c : present) {
        const GroupingTables& g = tables.at(c);
        std::vector<const std::vector<std::vector<double>>*> all;
        for (const auto& [s, t] : g.by_subject) all.push_back(&t);
        InformationRow row{c,
                           grouping,
                           g.by_subject.size(),
                           information_transmitted(sum_tables(all, g.x_categories.size(), g.y_categories.size())),
                           percentile(draws[c], 0.025),
                           percentile(draws[c], 0.975)};
        out.rows.push_back(std::move(row));
    }
    const std::size_t first = out.comparisons.size();
    for (std::size_t a = 0; a < present.size(); ++a)
        for (std::size_t b = a + 1; b < present.size(); ++b) {
            InformationComparison cmp{grouping, present[a], present[b], 0, 0, 0, 0, 0, 1, 1};
            const auto& ra = *std::find_if(out.rows.begin(), out.rows.end(), [&](const InformationRow& r) {
                return r.feature == grouping && r.condition == present[a];
            });
            const auto& rb = *std::find_if(out.rows.begin(), out.rows.end(), [&](const InformationRow& r) {
                return r.feature == grouping && r.condition == present[b];
            });
            cmp.rti_a = ra.t.rti;
            cmp.rti_b = rb.t.rti;
            cmp.difference = cmp.rti_a - cmp.rti_b;
            std::vector<double> d;
            std::size_t at_most_0 = 0, at_least_0 = 0;
            for (std::size_t k = 0; k < settings.bootstrap; ++k) {
                const double x = draws[present[a]][k] - draws[present[b]][k];
                if (!std::isfinite(x)) continue;
                d.push_back(x);
                at_most_0 += x <= 0.0 ? 1 : 0;
                at_least_0 += x >= 0.0 ? 1 : 0;
            }
            cmp.ci_low = percentile(d, 0.025);
            cmp.ci_high = percentile(d, 0.975);
            cmp.p = d.empty() ? std::numeric_limits<double>::quiet_NaN()
                              : std::clamp(2.0 * double(std::max<std::size_t>(1, std::min(at_most_0, at_least_0))) /
                                               double(d.size()),
                                           0.0, 1.0);
            out.comparisons.push_back(cmp);
        }
    std::vector<std::optional<double>> p;
    for (std::size_t i = first; i < out.comparisons.size(); ++i)
        p.push_back(std::isfinite(out.comparisons[i].p) ? std::optional<double>(out.comparisons[i].p) : std::nullopt);
    const auto adjusted = holm_adjust(p);
    for (std::size_t i = first; i < out.comparisons.size(); ++i)
        out.comparisons[i].p_holm = adjusted[i - first].value_or(std::numeric_limits<double>::quiet_NaN());
}

std::string csv_number_or_na(double x) { return std::isfinite(x) ? fmt::format("{:.6g}", x) : "NA"; }

}  // namespace

const std::vector<std::string>& feature_grouping_names() {
    static const std::vector<std::string> names = {"voicing", "manner", "place", "rounding", "viseme"};
    return names;
}

std::string feature_category(const std::string& grouping, const PhoneInfo& phone, bool as_response) {
    const bool consonant_grouping = grouping == "voicing" || grouping == "manner" || grouping == "place";
    if (consonant_grouping && is_vowel(phone)) return as_response ? k_other : "";
    if (grouping == "voicing") return feature(phone, Feature::Voiced) > 0.5f ? "voiced" : "voiceless";
    if (grouping == "manner") return manner_of(phone);
    if (grouping == "place") return place_of(phone);
    if (grouping == "rounding") return rounded(phone) ? "rounded" : "spread";
    if (grouping == "viseme") return to_string(viseme_class(phone));
    throw std::invalid_argument(fmt::format("feature_category: unknown grouping \"{}\"", grouping));
}

std::vector<ConfusionMatrix> confusion_matrices(const std::string& condition, const std::vector<PhonemeRow>& rows) {
    std::vector<PhonemeRow> mine;
    for (const auto& r : rows)
        if (r.condition == condition && r.outcome != PhoneOutcome::Inserted) mine.push_back(r);
    const std::string language = language_of_rows(rows);  // of the whole study, so all conditions share rows
    std::vector<ConfusionMatrix> out = {phone_matrix(condition, mine, false, language),
                                        phone_matrix(condition, mine, true, language)};
    std::vector<std::string> classes;
    for (int c = 0; c < static_cast<int>(VisemeClass::Count); ++c)
        classes.emplace_back(to_string(static_cast<VisemeClass>(c)));
    std::vector<std::string> columns = classes;
    columns.emplace_back(k_deleted);
    std::vector<std::pair<std::string, std::string>> pairs;
    for (const auto& r : mine)
        pairs.emplace_back(*category_of_row("viseme", r, false), *category_of_row("viseme", r, true));
    out.push_back(matrix_of(condition, "visemes", pairs, classes, columns));
    return out;
}

ConfusionMatrix feature_matrix(const std::string& condition, const std::string& grouping,
                               const std::vector<PhonemeRow>& rows) {
    const auto tables = grouping_tables(grouping, rows);
    ConfusionMatrix m{condition, grouping, {}, {}, {}};
    const auto it = tables.find(condition);
    if (it == tables.end()) return m;
    std::vector<const std::vector<std::vector<double>>*> all;
    for (const auto& [s, t] : it->second.by_subject) all.push_back(&t);
    m.rows = it->second.x_categories;
    m.columns = it->second.y_categories;
    m.counts = sum_tables(all, m.rows.size(), m.columns.size());
    return m;
}

InformationResult information_by_condition(const std::vector<PhonemeRow>& rows, const InformationSettings& settings) {
    InformationResult out;
    out.bootstrap = settings.bootstrap;
    out.seed = settings.seed;
    for (const auto& g : feature_grouping_names()) information_of_grouping(g, rows, settings, out);
    return out;
}

void write_confusions_csv(const std::filesystem::path& path, const std::vector<ConfusionMatrix>& matrices) {
    std::string out = "condition,kind,target,response,count,row_percent\n";
    for (const auto& m : matrices)
        for (std::size_t i = 0; i < m.rows.size(); ++i) {
            double total = 0.0;
            for (double c : m.counts[i]) total += c;
            for (std::size_t j = 0; j < m.columns.size(); ++j)
                out += csv_line({m.condition, m.kind, m.rows[i], m.columns[j], fmt::format("{:g}", m.counts[i][j]),
                                 total > 0.0 ? fmt::format("{:.2f}", 100.0 * m.counts[i][j] / total) : "NA"});
        }
    write_text_file(path, out);
}

void write_information_csv(const std::filesystem::path& path, const InformationResult& result) {
    std::string out =
        "condition,feature,subjects,phones,h_x,t_plugin,h_x_corrected,t_corrected,rti,ci_low,ci_high,"
        "correction,bootstrap,seed\n";
    for (const auto& r : result.rows)
        out += csv_line({r.condition, r.feature, std::to_string(r.subjects), fmt::format("{:g}", r.t.n),
                         csv_number_or_na(r.t.h_x), csv_number_or_na(r.t.t_plugin), csv_number_or_na(r.t.h_x_corrected),
                         csv_number_or_na(r.t.t_corrected), csv_number_or_na(r.t.rti), csv_number_or_na(r.ci_low),
                         csv_number_or_na(r.ci_high), "miller-madow", std::to_string(result.bootstrap),
                         std::to_string(result.seed)});
    write_text_file(path, out);
}

void write_information_comparisons_csv(const std::filesystem::path& path, const InformationResult& result) {
    std::string out = "feature,condition_a,condition_b,rti_a,rti_b,difference,ci_low,ci_high,p,p_holm,bootstrap\n";
    for (const auto& c : result.comparisons)
        out += csv_line({c.feature, c.condition_a, c.condition_b, csv_number_or_na(c.rti_a), csv_number_or_na(c.rti_b),
                         csv_number_or_na(c.difference), csv_number_or_na(c.ci_low), csv_number_or_na(c.ci_high),
                         csv_number_or_na(c.p), csv_number_or_na(c.p_holm), std::to_string(result.bootstrap)});
    write_text_file(path, out);
}

std::vector<PhonemeRow> read_phonemes_csv(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::size_t subject = table.require_column("subject"), condition = table.require_column("condition"),
                      sentence = table.require_column("sentence"), position = table.require_column("position"),
                      target = table.require_column("target"), response = table.require_column("response"),
                      outcome = table.require_column("outcome");
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::vector<PhonemeRow> out;
    std::vector<Diagnostic> problems;
    for (const auto& row : table.rows) {
        if (row.fields.size() < table.header.size()) {
            problems.push_back({path.string(), row.line, 1, "row",
                                fmt::format("expected {} fields, got {}", table.header.size(), row.fields.size())});
            continue;
        }
        const auto field = [&](std::size_t i) -> const std::string& { return row.fields.at(i); };
        PhonemeRow r;
        r.subject = field(subject);
        r.condition = field(condition);
        r.sentence = field(sentence);
        r.target = field(target);
        r.response = field(response);
        const auto pos = parse_int(field(position));
        if (!pos || *pos < 0)
            problems.push_back(
                {path.string(), row.line, 1, "position", fmt::format("expected a count, got \"{}\"", field(position))});
        else
            r.position = static_cast<std::size_t>(*pos);
        bool known = false;
        for (auto o : {PhoneOutcome::Correct, PhoneOutcome::Substituted, PhoneOutcome::Deleted, PhoneOutcome::Inserted})
            if (field(outcome) == outcome_name(o)) {
                r.outcome = o;
                known = true;
            }
        if (!known)
            problems.push_back(
                {path.string(), row.line, 1, "outcome",
                 fmt::format("expected correct, substituted, deleted or inserted, got \"{}\"", field(outcome))});
        for (const auto* s : {&r.target, &r.response})
            if (!s->empty() && !inventory.contains(*s))
                problems.push_back({path.string(), row.line, 1, s == &r.target ? "target" : "response",
                                    fmt::format("expected a phone of the phone set, got \"{}\"", *s)});
        const bool consistent = known && (r.outcome == PhoneOutcome::Inserted ? r.target.empty() && !r.response.empty()
                                          : r.outcome == PhoneOutcome::Deleted
                                              ? !r.target.empty() && r.response.empty()
                                              : !r.target.empty() && !r.response.empty() &&
                                                    ((r.target == r.response) == (r.outcome == PhoneOutcome::Correct)));
        if (known && !consistent)
            problems.push_back({path.string(), row.line, 1, "outcome",
                                fmt::format("\"{}\" does not fit target \"{}\" and response \"{}\"", field(outcome),
                                            r.target, r.response)});
        out.push_back(std::move(r));
    }
    if (!problems.empty()) throw InputError(problems);
    return out;
}

}  // namespace avsi::analysis
