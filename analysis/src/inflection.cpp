// Regular and listed English inflections for keyword scoring (see
// inflection.h). The spelling rules mirror scripts/make-inflections.
#include "avsi/analysis/inflection.h"

#include <algorithm>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/text.h"

namespace avsi::analysis {

namespace {

bool is_vowel(char c) { return c == 'a' || c == 'e' || c == 'i' || c == 'o' || c == 'u'; }

bool has_suffix(const std::string& s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Vowel groups (a rough syllable count: "stop" 1, "visit" 2, "travel" 2).
std::size_t vowel_groups(const std::string& b) {
    std::size_t groups = 0;
    bool in_vowel = false;
    for (char c : b) {
        const bool v = is_vowel(c) || (c == 'y' && groups > 0);
        if (v && !in_vowel) ++groups;
        in_vowel = v;
    }
    return groups;
}

// consonant + single vowel + consonant (not w, x, y) at the end: the final
// consonant doubles before -ed/-ing in one syllable (stop -> stopped, hat ->
// hatted, never hated) and may or may not in longer words, depending on
// stress and variety (prefer -> preferred, visit -> visited, travel ->
// travelled or traveled).
bool ends_cvc(const std::string& b) {
    const std::size_t n = b.size();
    if (n < 3) return false;
    const char last = b[n - 1];
    return !is_vowel(last) && last != 'w' && last != 'x' && last != 'y' && is_vowel(b[n - 2]) &&
           !is_vowel(b[n - 3]);
}

bool is_word_text(const std::string& w) {
    return !w.empty() && std::all_of(w.begin(), w.end(), [](char c) { return c >= 'a' && c <= 'z'; });
}

}  // namespace

std::vector<std::string> Inflections::regular_forms(const std::string& b, Suffix suffix) {
    const std::size_t n = b.size();
    const bool consonant_y = n >= 2 && b[n - 1] == 'y' && !is_vowel(b[n - 2]);
    switch (suffix) {
    case Suffix::S:
        if (has_suffix(b, "s") || has_suffix(b, "x") || has_suffix(b, "z") || has_suffix(b, "ch") || has_suffix(b, "sh"))
            return {b + "es"};
        if (consonant_y) return {b.substr(0, n - 1) + "ies"};
        if (n >= 2 && b[n - 1] == 'o' && !is_vowel(b[n - 2])) return {b + "es", b + "s"};
        return {b + "s"};
    case Suffix::Ed:
        if (has_suffix(b, "e")) return {b + "d"};
        if (consonant_y) return {b.substr(0, n - 1) + "ied"};
        if (ends_cvc(b)) return vowel_groups(b) == 1 ? std::vector<std::string>{b + b.back() + "ed"}
                                                     : std::vector<std::string>{b + b.back() + "ed", b + "ed"};
        return {b + "ed"};
    case Suffix::Ing:
        if (has_suffix(b, "ie")) return {b.substr(0, n - 2) + "ying"};
        if (has_suffix(b, "e") && !has_suffix(b, "ee") && !has_suffix(b, "ye") && !has_suffix(b, "oe") && n > 2)
            return {b.substr(0, n - 1) + "ing"};
        if (ends_cvc(b)) return vowel_groups(b) == 1 ? std::vector<std::string>{b + b.back() + "ing"}
                                                     : std::vector<std::string>{b + b.back() + "ing", b + "ing"};
        return {b + "ing"};
    }
    return {};
}

Inflections Inflections::read(const std::filesystem::path& table_path, const std::filesystem::path& pos_path) {
    Inflections out;
    DiagnosticList problems;
    {
        const CsvTable table = read_csv(table_path);
        const std::size_t c_form = table.require_column("form");
        const std::size_t c_lemma = table.require_column("lemma");
        const std::size_t c_relation = table.require_column("relation");
        for (const auto& row : table.rows) {
            const std::string form = trim(row.fields[c_form]), lemma = trim(row.fields[c_lemma]);
            const std::string relation = trim(row.fields[c_relation]);
            for (const auto& [column, value, name] :
                 {std::tuple{c_form, form, "form"}, std::tuple{c_lemma, lemma, "lemma"}})
                if (!is_word_text(value))
                    problems.add(table_path.string(), row.line, int(column) + 1, name,
                                 fmt::format("expected a lower-case word (a-z), got \"{}\"", value));
            if (relation == "irregular") {
                out.m_irregular[form].push_back(lemma);
                ++out.m_irregular_count;
            } else if (relation == "not") {
                out.m_not.emplace(form, lemma);
            } else {
                problems.add(table_path.string(), row.line, int(c_relation) + 1, "relation",
                             fmt::format("expected \"irregular\" or \"not\", got \"{}\"", relation));
            }
        }
    }
    {
        CsvOptions options;
        options.delimiter = '\t';
        const CsvTable table = read_csv(pos_path, options);
        const std::size_t c_word = table.require_column("word");
        const std::size_t c_pos = table.require_column("pos");
        out.m_pos.reserve(table.rows.size());
        for (const auto& row : table.rows) {
            const std::string word = trim(row.fields[c_word]), pos = trim(row.fields[c_pos]);
            std::uint8_t bits = 0;
            bool ok = !pos.empty() && is_word_text(word);
            for (char c : pos) {
                if (c == 'n') bits |= Noun;
                else if (c == 'v') bits |= Verb;
                else ok = false;
            }
            if (!ok)
                problems.add(pos_path.string(), row.line, 0, "pos",
                             fmt::format("expected a lower-case word and parts of speech from \"nv\", got \"{}\" \"{}\"",
                                         word, pos));
            else
                out.m_pos[word] = bits;
        }
    }
    problems.throw_if_any();
    return out;
}

Inflections Inflections::read_default() {
    const std::filesystem::path dir(AVSI_PROTOCOLS_DIR);
    return read(dir / "inflections.csv", dir / "lemma_pos.tsv");
}

std::uint8_t Inflections::pos_of(const std::string& word) const {
    const auto it = m_pos.find(word);
    return it == m_pos.end() ? 0 : it->second;
}

std::uint8_t Inflections::base_pos_of(const std::string& word, const OpenWords* open) const {
    const std::uint8_t pos = pos_of(word);
    return pos != 0 ? pos : open && open->count(word) ? std::uint8_t(Noun | Verb) : std::uint8_t(0);
}

std::vector<std::string> Inflections::lemmas(const std::string& w, const OpenWords* open) const {
    std::vector<std::string> out{w};
    if (!is_word_text(w)) return out;  // numbers and the like inflect by no rule
    auto add_base = [&](const std::string& base, Suffix suffix) {
        if (base.size() < 2 || std::find(out.begin(), out.end(), base) != out.end()) return;
        const std::uint8_t pos = base_pos_of(base, open);
        if (suffix == Suffix::S ? (pos & (Noun | Verb)) == 0 : (pos & Verb) == 0) return;
        if (m_not.count({w, base})) return;
        const auto forms = regular_forms(base, suffix);
        if (std::find(forms.begin(), forms.end(), w) != forms.end()) out.push_back(base);
    };
    const std::size_t n = w.size();
    // -s, -es, -ies
    if (has_suffix(w, "s")) {
        add_base(w.substr(0, n - 1), Suffix::S);
        if (has_suffix(w, "es")) add_base(w.substr(0, n - 2), Suffix::S);
        if (has_suffix(w, "ies")) add_base(w.substr(0, n - 3) + "y", Suffix::S);
    }
    // An -ed or -ing form that is itself a verb (feed, need, bed, sing) is a base form.
    const bool is_verb = (pos_of(w) & Verb) != 0;
    if (!is_verb && has_suffix(w, "ed")) {
        add_base(w.substr(0, n - 1), Suffix::Ed);  // -d after e
        add_base(w.substr(0, n - 2), Suffix::Ed);
        if (n >= 4 && w[n - 3] == w[n - 4]) add_base(w.substr(0, n - 3), Suffix::Ed);  // doubled
        if (has_suffix(w, "ied")) add_base(w.substr(0, n - 3) + "y", Suffix::Ed);
    }
    if (!is_verb && has_suffix(w, "ing")) {
        add_base(w.substr(0, n - 3), Suffix::Ing);
        add_base(w.substr(0, n - 3) + "e", Suffix::Ing);
        if (n >= 5 && w[n - 4] == w[n - 5]) add_base(w.substr(0, n - 4), Suffix::Ing);  // doubled
        if (has_suffix(w, "ying")) add_base(w.substr(0, n - 4) + "ie", Suffix::Ing);
    }
    // -men plurals of -man nouns (women, mailmen): WordNet makes them by a
    // detachment rule, so its exception list (our irregular table) lacks them.
    if (n > 3 && has_suffix(w, "men")) {
        const std::string base = w.substr(0, n - 3) + "man";
        if ((pos_of(base) & Noun) != 0 && std::find(out.begin(), out.end(), base) == out.end()) out.push_back(base);
    }
    if (const auto it = m_irregular.find(w); it != m_irregular.end())
        for (const auto& lemma : it->second)
            if (std::find(out.begin(), out.end(), lemma) == out.end()) out.push_back(lemma);
    return out;
}

std::vector<std::string> Inflections::irregular_forms_of(const std::string& lemma) const {
    std::vector<std::string> out;
    for (const auto& [form, lemmas] : m_irregular)
        if (std::find(lemmas.begin(), lemmas.end(), lemma) != lemmas.end()) out.push_back(form);
    std::sort(out.begin(), out.end());
    return out;
}

bool Inflections::same_lemma(const std::string& a, const std::string& b, const OpenWords* open) const {
    if (a == b) return true;
    const auto la = lemmas(a, open), lb = lemmas(b, open);
    for (const auto& x : la)
        if (std::find(lb.begin(), lb.end(), x) != lb.end()) return true;
    return false;
}

}  // namespace avsi::analysis
