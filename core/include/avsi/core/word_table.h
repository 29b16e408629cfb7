// English word frequencies, parts of speech and function words for the
// corpus tools (list_balance.h, keyword_proposals.h): a keyword's log
// frequency is that of its lemma, found through the table's irregular forms
// and core's morphology (morphology.h).
//
// Tables (protocols/corpus/): word-frequency.tsv, the SemCor sense-tagged
// count of each WordNet 3.0 lemma with its parts of speech and WordNet's
// irregular forms (scripts/make-word-frequency); function-words.txt;
// word-zipf.tsv, word-form frequencies on the Zipf scale (scripts/make-word-zipf).
//
//   const avsi::WordTable& words = avsi::WordTable::builtin();
//   words.log_frequency("barked");   // log10(1 + count of "bark")
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace avsi {

// One lemma a word form can come from, with its frequency.
struct WordFrequency {
    std::string lemma;
    long long count = 0;   // SemCor tag count of the lemma (all senses, all parts of speech)
    std::string pos;       // WordNet parts of speech: letters of "nvar"
};

// Word frequencies, parts of speech and function words.
class WordTable {
public:
    // protocols/corpus/word-frequency.tsv, protocols/corpus/function-words.txt
    // and protocols/corpus/word-zipf.tsv (loaded once).
    static const WordTable& builtin();
    // Reads a frequency table (word, lemma, count, pos; '#' comments), a
    // function-word list (one word a line) and optionally a Zipf table (word,
    // zipf). Throws InputError naming file:line.
    static WordTable load(const std::filesystem::path& frequency_tsv,
                          const std::filesystem::path& function_words,
                          const std::filesystem::path& zipf_tsv = {});

    // The lemmas `word` (any case; a possessive 's removed) can be a form of,
    // highest count first: the table's own rows (lemma or irregular form),
    // then the bases it is a regular inflection of (morphology.h: dogs → dog,
    // barked → bark, bigger → big) where the table has the base as a lemma
    // of a part of speech that takes the suffix. Empty when unknown.
    std::vector<WordFrequency> lookup(std::string_view word) const;
    // log10(1 + count) of the most frequent lemma; 0 for an unknown word.
    double log_frequency(std::string_view word) const;
    bool is_function_word(std::string_view word) const;
    // The word form's frequency on the Zipf scale, log10(per billion words),
    // from the Zipf table (scripts/make-word-zipf: CMU Sphinx's US English
    // language model); nullopt when the table does not know the form.
    std::optional<double> zipf(std::string_view word) const;
    std::size_t size() const { return m_rows.size(); }

private:
    std::multimap<std::string, WordFrequency, std::less<>> m_rows;
    std::map<std::string, std::string, std::less<>> m_lemma_pos;  // lemma → parts of speech
    std::set<std::string, std::less<>> m_function_words;
    std::map<std::string, double, std::less<>> m_zipf;
};

}  // namespace avsi
