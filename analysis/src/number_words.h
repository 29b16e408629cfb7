// Number words of Swedish and German for keyword scoring
// (text_normalize.h step 5 for those languages; English has its own in
// text_normalize.cpp). Both languages write a number below a million as one
// word built from parts: Swedish tjugo+en (21), ett+hundra+fem (105),
// två+tusen (2000); German ein+und+zwanzig (21), zwei+hundert+drei (203).
// A word is read as a number when it splits into such parts in an order the
// grammar allows:
//   below100  = teen | unit | ten [unit]        (Swedish: tens first)
//             = teen | unit | ten | unit und ten (German: units first)
//   below1000 = [unit | teen] hundred [below100] | below100
//   number    = [below1000] thousand [below1000] | below1000
// Words typed apart ("tjugo en", "ein und zwanzig") are joined first: the
// longest run of words whose concatenation is a number is one number.
// Not numbers on their own: the indefinite articles that double as "one"
// (Swedish en/ett, German ein); inside a number they count (tjugoen,
// etthundra, einundzwanzig). Ordinals (femte, fünfte) are not converted.
// Sources: Svenska Akademiens grammatik (1999) on cardinal numerals and
// Duden, Die Grammatik (2016) §§ on Kardinalzahlen; the colloquial Swedish
// tens without -o (fyrti, femti) are listed as well.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace avsi::analysis::detail {

enum class NumberPart { Unit, Teen, Ten, Hundred, Thousand, And };

struct NumberMorpheme {
    std::string_view text;  // UTF-8, lower case
    NumberPart part;
    long long value;
};

struct NumberGrammar {
    std::vector<NumberMorpheme> morphemes;
    bool units_before_tens = false;        // German einundzwanzig
    std::vector<std::string_view> alone_not_numbers;  // articles: en, ett; ein
};

const NumberGrammar& swedish_number_grammar();
const NumberGrammar& german_number_grammar();

// The value of one lower-case word under `grammar`, or nullopt.
std::optional<long long> parse_number_word(std::string_view word, const NumberGrammar& grammar);

// The grammar of a language code, or nullptr (English is handled apart).
const NumberGrammar* number_grammar_of(std::string_view language);

}  // namespace avsi::analysis::detail
