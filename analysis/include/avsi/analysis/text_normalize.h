// Text normalisation for keyword scoring. Responses, keywords, alternates and
// the homophone table all pass through the same steps, in this order:
//   1. UTF-8 decoding; Latin letters with diacritics folded to ASCII
//      ("café" -> "cafe", "straße" -> "strasse"); curly apostrophes -> '.
//   2. lower case; thousands separators inside numbers removed ("1,000").
//   3. split into words at anything but letters, digits and apostrophes
//      (so hyphens and punctuation separate words).
//   4. common English contractions expanded ("don't" -> "do not",
//      "won't" -> "will not", "it's" -> "it is"); any other "'s" is taken as
//      a possessive and removed ("dog's" -> "dog"); remaining apostrophes dropped.
//   5. numbers written as words become digits ("seven" -> "7",
//      "twenty one" -> "21", "one hundred and five" -> "105"), ordinals too
//      ("first" -> "1st", "twenty-first" -> "21st"), so "7" and "seven" compare equal.
// That is English (language "en"). Other languages (language.h) change steps
// 1, 4 and 5:
//   1. the language's own letters are kept as letters, lower-cased (Swedish
//      å ä ö é, German ä ö ü ß; far and får, schon and schön are different
//      words); other diacritics are folded as for English;
//   4. no contractions; apostrophes are dropped ("geht's" -> "gehts");
//   5. the language's number words become digits ("fem" -> "5", "tjugoen" and
//      "tjugo en" -> "21", "einundzwanzig" -> "21"; analysis/src/number_words.h).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace avsi::analysis {

// The normalised words of a text (steps 1-5 above).
std::vector<std::string> normalize_words(std::string_view text);

// One normalised word and how it was written.
struct NormalizedWord {
    std::string text;
    bool number_in_words = false;  // a number written in words ("seven" -> "7", "first" -> "1st")
};

// normalize_words with, for each word, whether step 5 made it from number words.
std::vector<NormalizedWord> normalize_tokens(std::string_view text);

// Steps 1-2 alone: lower-case ASCII letters, digits, apostrophes and
// spaces (anything else, and a separator of thousands kept out, becomes a space).
std::string fold_to_ascii(std::string_view text);

// The normalised words joined by single spaces.
std::string normalize_text(std::string_view text);

// The same for a language code of language.h ("en" is the functions above).
std::vector<NormalizedWord> normalize_tokens(std::string_view text, std::string_view language);
std::vector<std::string> normalize_words(std::string_view text, std::string_view language);

// Steps 1-3 alone for a language that keeps letters of its own (Swedish,
// German): its words, lower case, its letters kept, apostrophes dropped,
// digits as written; nullopt for a language that keeps none (English).
std::optional<std::vector<std::string>> words_keeping_letters(std::string_view text, std::string_view language);

// A normalised word in the plain-ASCII spelling a keyboard without the
// language's letters gives: German ä ö ü ß -> ae oe ue ss, Swedish é -> e
// (Swedish å ä ö have no such spelling); English words are unchanged.
std::string ascii_spelling(std::string_view normalized_word, std::string_view language);

}  // namespace avsi::analysis
