// Swedish and German number words (see number_words.h).
#include "number_words.h"

namespace avsi::analysis::detail {

namespace {

struct ParseState {
    long long total = 0, current = 0;
    std::optional<NumberPart> last;
};

// Does `m` fit after `s` (number_words.h's grammar)? Applies it when it does.
bool apply(ParseState& s, const NumberMorpheme& m, bool units_before_tens) {
    const auto last = s.last;
    const bool after_scale = !last || *last == NumberPart::Hundred || *last == NumberPart::Thousand;
    bool fits = false;
    switch (m.part) {
    case NumberPart::Unit:
        fits = after_scale || (!units_before_tens && *last == NumberPart::Ten && s.current % 10 == 0);
        if (fits) s.current += m.value;
        break;
    case NumberPart::Teen:
        fits = after_scale;
        if (fits) s.current += m.value;
        break;
    case NumberPart::Ten:
        fits = after_scale || (units_before_tens && *last == NumberPart::And);
        if (fits) s.current += m.value;
        break;
    case NumberPart::And:
        fits = units_before_tens && last && *last == NumberPart::Unit;
        break;
    case NumberPart::Hundred:
        fits = !last || ((*last == NumberPart::Unit || *last == NumberPart::Teen) && s.current > 0 && s.current < 100);
        if (fits) s.current = (s.current == 0 ? 1 : s.current) * 100;
        break;
    case NumberPart::Thousand:
        fits = s.total == 0 && (!last || *last != NumberPart::And);
        if (fits) {
            s.total = (s.current == 0 ? 1 : s.current) * 1000;
            s.current = 0;
        }
        break;
    }
    if (fits) s.last = m.part;
    return fits;
}

// Depth-first over the ways `rest` splits into morphemes.
std::optional<long long> parse_from(std::string_view rest, const ParseState& s, const NumberGrammar& g) {
    if (rest.empty()) {
        if (!s.last || *s.last == NumberPart::And) return std::nullopt;
        return s.total + s.current;
    }
    for (const auto& m : g.morphemes) {
        if (rest.substr(0, m.text.size()) != m.text) continue;
        ParseState next = s;
        if (!apply(next, m, g.units_before_tens)) continue;
        if (auto v = parse_from(rest.substr(m.text.size()), next, g)) return v;
    }
    return std::nullopt;
}

}  // namespace

const NumberGrammar& swedish_number_grammar() {
    using P = NumberPart;
    static const NumberGrammar g{
        {{"noll", P::Unit, 0},       {"ett", P::Unit, 1},        {"en", P::Unit, 1},        {"två", P::Unit, 2},
         {"tre", P::Unit, 3},        {"fyra", P::Unit, 4},       {"fem", P::Unit, 5},       {"sex", P::Unit, 6},
         {"sju", P::Unit, 7},        {"åtta", P::Unit, 8},       {"nio", P::Unit, 9},       {"tio", P::Teen, 10},
         {"elva", P::Teen, 11},      {"tolv", P::Teen, 12},      {"tretton", P::Teen, 13},  {"fjorton", P::Teen, 14},
         {"femton", P::Teen, 15},    {"sexton", P::Teen, 16},    {"sjutton", P::Teen, 17},  {"arton", P::Teen, 18},
         {"aderton", P::Teen, 18},   {"nitton", P::Teen, 19},    {"tjugo", P::Ten, 20},     {"tjugu", P::Ten, 20},
         {"trettio", P::Ten, 30},    {"tretti", P::Ten, 30},     {"fyrtio", P::Ten, 40},    {"fyrti", P::Ten, 40},
         {"femtio", P::Ten, 50},     {"femti", P::Ten, 50},      {"sextio", P::Ten, 60},    {"sexti", P::Ten, 60},
         {"sjuttio", P::Ten, 70},    {"sjutti", P::Ten, 70},     {"åttio", P::Ten, 80},     {"åtti", P::Ten, 80},
         {"nittio", P::Ten, 90},     {"nitti", P::Ten, 90},      {"hundra", P::Hundred, 100},
         {"tusen", P::Thousand, 1000}},
        false,
        {"en", "ett"}};
    return g;
}

const NumberGrammar& german_number_grammar() {
    using P = NumberPart;
    static const NumberGrammar g{
        {{"null", P::Unit, 0},        {"eins", P::Unit, 1},         {"ein", P::Unit, 1},         {"zwei", P::Unit, 2},
         {"zwo", P::Unit, 2},         {"drei", P::Unit, 3},         {"vier", P::Unit, 4},        {"fünf", P::Unit, 5},
         {"sechs", P::Unit, 6},       {"sieben", P::Unit, 7},       {"acht", P::Unit, 8},        {"neun", P::Unit, 9},
         {"zehn", P::Teen, 10},       {"elf", P::Teen, 11},         {"zwölf", P::Teen, 12},      {"dreizehn", P::Teen, 13},
         {"vierzehn", P::Teen, 14},   {"fünfzehn", P::Teen, 15},    {"sechzehn", P::Teen, 16},   {"siebzehn", P::Teen, 17},
         {"achtzehn", P::Teen, 18},   {"neunzehn", P::Teen, 19},    {"zwanzig", P::Ten, 20},     {"dreißig", P::Ten, 30},
         {"dreissig", P::Ten, 30},    {"vierzig", P::Ten, 40},      {"fünfzig", P::Ten, 50},     {"sechzig", P::Ten, 60},
         {"siebzig", P::Ten, 70},     {"achtzig", P::Ten, 80},      {"neunzig", P::Ten, 90},     {"und", P::And, 0},
         {"hundert", P::Hundred, 100}, {"tausend", P::Thousand, 1000}},
        true,
        {"ein"}};
    return g;
}

std::optional<long long> parse_number_word(std::string_view word, const NumberGrammar& grammar) {
    if (word.empty()) return std::nullopt;
    return parse_from(word, ParseState{}, grammar);
}

const NumberGrammar* number_grammar_of(std::string_view language) {
    if (language == "sv") return &swedish_number_grammar();
    if (language == "de") return &german_number_grammar();
    return nullptr;
}

}  // namespace avsi::analysis::detail
