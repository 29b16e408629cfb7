// The languages of keyword scoring and the tables each one uses
// (docs/scoring.md "Languages"). A language is named by its ISO 639-1 code,
// the code espeak-ng's voice names start with ("sv", "de", "en-us"):
//   en  English: ASCII folding, English contractions and number words, the
//       General American homophones (protocols/homophones.csv), US/UK
//       spellings, WordNet inflections, the SCOWL word lists;
//   sv  Swedish: å ä ö kept as letters (far and får are different words),
//       Swedish number words (fem 5, tjugoen 21, etthundra 100), homophones
//       vetted with espeak-ng's sv voice, and hunspell-sv (libhunspell) for
//       words, compounds and the stems of inflections (definite -en/-et,
//       plural -ar/-or/-er and their combinations) — no hand-written suffix
//       rules; the word list of wswedish beside it;
//   de  German: ä ö ü ß kept (ae oe ue ss are accepted as spellings of
//       them), German number words (fünf 5, einundzwanzig 21), homophones
//       vetted with espeak-ng's de voice, hunspell-de-de and wngerman.
// The per-language files live in protocols/languages/<code>/scoring/; English
// keeps its tables where they were (protocols/*.csv) so its outputs are
// byte-identical.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace avsi::analysis {

struct ScoringLanguage {
    std::string code;  // "en", "sv", "de"
    std::string name;  // "English", "Swedish", "German"
    std::filesystem::path homophones;         // the default homophone table
    std::filesystem::path spelling_variants;  // the spelling-variant groups
    // The hunspell dictionary (/usr/share/hunspell/<name>.aff and .dic) and
    // its Debian package; empty for English (WordNet tables and SCOWL lists).
    std::string hunspell, hunspell_package;
    // The Debian word list of the lexicon and its package.
    std::vector<std::filesystem::path> word_lists;
    std::string word_list_package;
};

// The codes keyword scoring has tables for, in this order: en, sv, de.
const std::vector<std::string>& scoring_language_codes();

// The language of that code; throws InputError naming the known codes for
// an unknown one.
const ScoringLanguage& scoring_language(std::string_view code);

}  // namespace avsi::analysis
