// Inflection, not stemming: the rule "inflection" of the loose and lenient
// rule sets (scoring.h). Two words match when they are forms of one lemma
// through a regular or a listed inflection:
//   - regular: plural and third person -s, past -ed and -ing, spelled by
//     core's English morphology (core/morphology.h: -es, -ies, -ied, -ying,
//     a final e dropped, a final consonant doubled or not). Possessives are
//     removed by normalisation (text_normalize.h) before. The base must be
//     a WordNet noun or verb for -s and a verb for -ed and -ing
//     (protocols/lemma_pos.tsv), and an -ed/-ing form that is itself a verb
//     (feed, need, bed) is not a past or participle of anything;
//   - listed: the irregular forms of protocols/inflections.csv (children ->
//     child, rang -> ring, went -> go), from WordNet's exception lists;
//   - not: forms listed there as words of their own are never inflections of
//     what their spelling suggests (evening is not even + ing).
// So boys/boy, windows/window, helps/helped match; even/evening (listed
// "not"), engineer/engine (-er is not an inflection), cloth/clothes (the
// plural of cloth is cloths; clothes is clothe + s) and rang/range do not.
// Sources and generation: scripts/make-inflections.
#pragma once

#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace avsi::analysis {

class Inflections {
public:
    // Reads the inflection table (form,lemma,relation with relation irregular
    // or not) and the parts of speech (word<TAB>pos, pos letters n and v).
    // Throws InputError naming file, line and field for a bad row.
    static Inflections read(const std::filesystem::path& table, const std::filesystem::path& parts_of_speech);
    // The shipped protocols/inflections.csv and protocols/lemma_pos.tsv.
    static Inflections read_default();

    // Words (the corpus's) that may be the base of a regular inflection as a
    // noun or a verb when WordNet gives them no part of speech.
    using OpenWords = std::set<std::string, std::less<>>;

    // The lemmas `word` is a form of: itself, the bases it is a regular
    // inflection of (including the -men plural of a -man noun), and the
    // lemmas it is a listed irregular form of.
    std::vector<std::string> lemmas(const std::string& word, const OpenWords* open = nullptr) const;

    // Do the two normalised words share a lemma?
    bool same_lemma(const std::string& a, const std::string& b, const OpenWords* open = nullptr) const;

    std::size_t irregular_count() const { return m_irregular_count; }

    // Is `word` a noun in WordNet (protocols/lemma_pos.tsv)?
    bool is_noun(const std::string& word) const { return (pos_of(word) & Noun) != 0; }
    // The listed irregular forms of `lemma` (child → children; ring → rang, rung).
    std::vector<std::string> irregular_forms_of(const std::string& lemma) const;

private:
    enum : std::uint8_t { Noun = 1, Verb = 2 };
    std::uint8_t pos_of(const std::string& word) const;       // WordNet's
    std::uint8_t base_pos_of(const std::string& word, const OpenWords* open) const;  // or n+v for open words

    std::unordered_map<std::string, std::vector<std::string>> m_irregular;  // form -> lemmas
    std::set<std::pair<std::string, std::string>> m_not;                     // (form, lemma)
    std::unordered_map<std::string, std::uint8_t> m_pos;
    std::size_t m_irregular_count = 0;
};

}  // namespace avsi::analysis
