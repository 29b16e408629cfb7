// The word table of the corpus tools (word_table.h): WordNet lemma counts,
// parts of speech and irregular forms, function words and Zipf frequencies;
// a form's lemmas through core's morphology (morphology.h).
#include "avsi/core/word_table.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/morphology.h"
#include "avsi/core/text.h"

namespace avsi {

namespace {

bool ends_with(std::string_view s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

}  // namespace

const WordTable& WordTable::builtin() {
    static const WordTable table = load(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "word-frequency.tsv",
                                        std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "function-words.txt",
                                        std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "word-zipf.tsv");
    return table;
}

WordTable WordTable::load(const std::filesystem::path& frequency_tsv, const std::filesystem::path& function_words,
                          const std::filesystem::path& zipf_tsv) {
    WordTable t;
    CsvOptions options;
    options.delimiter = '\t';
    const CsvTable table = read_csv(frequency_tsv, options);
    const std::size_t c_word = table.require_column("word");
    const std::size_t c_lemma = table.require_column("lemma");
    const std::size_t c_count = table.require_column("count");
    const std::size_t c_pos = table.require_column("pos");
    DiagnosticList problems;
    const std::string p = frequency_tsv.string();
    for (const auto& row : table.rows) {
        const auto count = parse_int(row.fields[c_count]);
        if (!count || *count < 0) {
            problems.add(p, row.line, 0, "count",
                         fmt::format("expected a count ≥ 0, got \"{}\"", row.fields[c_count]));
            continue;
        }
        const std::string pos = row.fields[c_pos];
        if (pos.find_first_not_of("nvar") != std::string::npos)
            problems.add(p, row.line, 0, "pos", fmt::format("expected letters of \"nvar\", got \"{}\"", pos));
        WordFrequency f{ascii_lower(row.fields[c_lemma]), *count, pos};
        const std::string word = ascii_lower(row.fields[c_word]);
        if (word == f.lemma) t.m_lemma_pos[f.lemma] = pos;
        t.m_rows.emplace(word, std::move(f));
    }
    problems.throw_if_any();
    std::istringstream in(read_text_file(function_words));
    std::string line;
    while (std::getline(in, line)) {
        line = trim(line);
        if (line.empty() || line[0] == '#') continue;
        t.m_function_words.insert(ascii_lower(line));
    }
    if (!zipf_tsv.empty()) {
        const CsvTable z = read_csv(zipf_tsv, options);
        const std::size_t c_zword = z.require_column("word");
        const std::size_t c_zipf = z.require_column("zipf");
        for (const auto& row : z.rows) {
            const auto v = parse_double(row.fields[c_zipf]);
            if (!v || !std::isfinite(*v)) {
                problems.add(zipf_tsv.string(), row.line, 0, "zipf",
                             fmt::format("expected a number, got \"{}\"", row.fields[c_zipf]));
                continue;
            }
            t.m_zipf[ascii_lower(row.fields[c_zword])] = *v;
        }
        problems.throw_if_any();
    }
    return t;
}

std::optional<double> WordTable::zipf(std::string_view word_in) const {
    std::string word = ascii_lower(word_in);
    auto it = m_zipf.find(word);
    if (it == m_zipf.end() && ends_with(word, "'s")) it = m_zipf.find(word.substr(0, word.size() - 2));
    if (it == m_zipf.end()) return std::nullopt;
    return it->second;
}

std::vector<WordFrequency> WordTable::lookup(std::string_view word_in) const {
    std::string word = ascii_lower(word_in);
    if (ends_with(word, "'s")) word.resize(word.size() - 2);
    std::vector<WordFrequency> out;
    auto add = [&](const WordFrequency& f) {
        for (const auto& o : out)
            if (o.lemma == f.lemma) return;
        out.push_back(f);
    };
    const auto [first, last] = m_rows.equal_range(word);
    for (auto it = first; it != last; ++it) add(it->second);
    const auto pos_of = [&](const std::string& w) {
        const auto it = m_lemma_pos.find(w);
        return it == m_lemma_pos.end() ? PartsOfSpeech{} : parts_of_speech(it->second);
    };
    for (const RegularBase& b : regular_bases(word, pos_of(word))) {
        if (!b.takes(pos_of(b.base))) continue;
        const auto [f, l] = m_rows.equal_range(b.base);
        for (auto r = f; r != l; ++r)
            if (r->second.lemma == b.base) add(r->second);
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const WordFrequency& a, const WordFrequency& b) { return a.count > b.count; });
    return out;
}

double WordTable::log_frequency(std::string_view word) const {
    const auto found = lookup(word);
    return found.empty() ? 0.0 : std::log10(1.0 + static_cast<double>(found.front().count));
}

bool WordTable::is_function_word(std::string_view word) const {
    return m_function_words.count(ascii_lower(word)) > 0;
}

}  // namespace avsi
