// Regular and listed English inflections for keyword scoring (see
// inflection.h): the regular ones by core's morphology (morphology.h), the
// listed ones and the parts of speech from the shipped tables.
#include "avsi/analysis/inflection.h"

#include <algorithm>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/morphology.h"
#include "avsi/core/text.h"

namespace avsi::analysis {

namespace {

bool is_word_text(const std::string& w) {
    return !w.empty() && std::all_of(w.begin(), w.end(), [](char c) { return c >= 'a' && c <= 'z'; });
}

}  // namespace

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
    PartsOfSpeech form_pos;
    form_pos.verb = (pos_of(w) & Verb) != 0;
    for (const RegularBase& b : regular_bases(w, form_pos)) {
        if (std::find(out.begin(), out.end(), b.base) != out.end()) continue;
        // A -men plural needs a WordNet noun; the regular suffixes also take
        // open words, and never make a form listed as a word of its own.
        if (b.men_plural) {
            if ((pos_of(b.base) & Noun) != 0) out.push_back(b.base);
            continue;
        }
        const std::uint8_t pos = base_pos_of(b.base, open);
        if (!b.takes({.noun = (pos & Noun) != 0, .verb = (pos & Verb) != 0}) || m_not.count({w, b.base})) continue;
        out.push_back(b.base);
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
