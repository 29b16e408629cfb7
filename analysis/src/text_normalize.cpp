// Text normalisation for keyword scoring (see text_normalize.h for the steps).
#include "avsi/analysis/text_normalize.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <map>
#include <optional>

#include "number_words.h"

namespace avsi::analysis {

namespace {

// ASCII folding of Latin-1 Supplement and Latin Extended-A letters
// (U+00C0..U+017F); nullptr for code points that are not letters.
const char* fold_latin(char32_t c) {
    static const std::map<char32_t, const char*> table = {
        {U'À', "a"}, {U'Á', "a"}, {U'Â', "a"}, {U'Ã', "a"}, {U'Ä', "a"}, {U'Å', "a"}, {U'Æ', "ae"},
        {U'Ç', "c"}, {U'È', "e"}, {U'É', "e"}, {U'Ê', "e"}, {U'Ë', "e"}, {U'Ì', "i"}, {U'Í', "i"},
        {U'Î', "i"}, {U'Ï', "i"}, {U'Ð', "d"}, {U'Ñ', "n"}, {U'Ò', "o"}, {U'Ó', "o"}, {U'Ô', "o"},
        {U'Õ', "o"}, {U'Ö', "o"}, {U'Ø', "o"}, {U'Ù', "u"}, {U'Ú', "u"}, {U'Û', "u"}, {U'Ü', "u"},
        {U'Ý', "y"}, {U'Þ', "th"}, {U'ß', "ss"}, {U'à', "a"}, {U'á', "a"}, {U'â', "a"}, {U'ã', "a"},
        {U'ä', "a"}, {U'å', "a"}, {U'æ', "ae"}, {U'ç', "c"}, {U'è', "e"}, {U'é', "e"}, {U'ê', "e"},
        {U'ë', "e"}, {U'ì', "i"}, {U'í', "i"}, {U'î', "i"}, {U'ï', "i"}, {U'ð', "d"}, {U'ñ', "n"},
        {U'ò', "o"}, {U'ó', "o"}, {U'ô', "o"}, {U'õ', "o"}, {U'ö', "o"}, {U'ø', "o"}, {U'ù', "u"},
        {U'ú', "u"}, {U'û', "u"}, {U'ü', "u"}, {U'ý', "y"}, {U'þ', "th"}, {U'ÿ', "y"}, {U'Œ', "oe"},
        {U'œ', "oe"}, {U'Ł', "l"}, {U'ł', "l"}, {U'Đ', "d"}, {U'đ', "d"}, {U'Ħ', "h"}, {U'ħ', "h"},
        {U'ı', "i"}, {U'Ŀ', "l"}, {U'ŀ', "l"}, {U'Ŋ', "n"}, {U'ŋ', "n"}, {U'Ŧ', "t"}, {U'ŧ', "t"},
        {U'ĸ', "k"}, {U'ŉ', "n"}, {U'Ĳ', "ij"}, {U'ĳ', "ij"}, {U'ſ', "s"}};
    if (auto it = table.find(c); it != table.end()) return it->second;
    // Latin Extended-A letters with a diacritic on a plain base letter, in
    // the Unicode order of their base letters (pairs upper/lower).
    static const std::array<std::pair<char32_t, const char*>, 21> ranges = {{
        {U'Ā', "a"}, {U'Ć', "c"}, {U'Ď', "d"}, {U'Ē', "e"}, {U'Ĝ', "g"}, {U'Ĥ', "h"}, {U'Ĩ', "i"},
        {U'Ĵ', "j"}, {U'Ķ', "k"}, {U'Ĺ', "l"}, {U'Ń', "n"}, {U'Ō', "o"}, {U'Ŕ', "r"}, {U'Ś', "s"},
        {U'Ţ', "t"}, {U'Ũ', "u"}, {U'Ŵ', "w"}, {U'Ŷ', "y"}, {U'Ÿ', "y"}, {U'Ź', "z"}, {U'ƀ', nullptr},
    }};
    if (c >= U'Ā' && c < U'ƀ')
        for (std::size_t i = 0; i + 1 < ranges.size(); ++i)
            if (c >= ranges[i].first && c < ranges[i + 1].first) return ranges[i].second;
    return nullptr;
}

// Decodes one UTF-8 code point at s[i], advancing i; invalid bytes give U+FFFD.
char32_t next_code_point(std::string_view s, std::size_t& i) {
    const auto b0 = static_cast<unsigned char>(s[i++]);
    if (b0 < 0x80) return b0;
    int extra = b0 >= 0xF0 ? 3 : b0 >= 0xE0 ? 2 : b0 >= 0xC0 ? 1 : -1;
    if (extra < 0) return 0xFFFD;
    char32_t c = b0 & (0x3F >> extra);
    for (int k = 0; k < extra; ++k) {
        if (i >= s.size() || (static_cast<unsigned char>(s[i]) & 0xC0) != 0x80) return 0xFFFD;
        c = (c << 6) | (static_cast<unsigned char>(s[i++]) & 0x3F);
    }
    return c;
}

}  // namespace

// Steps 1-2: an ASCII string of lower-case letters, digits, apostrophes and
// spaces (everything else becomes a space).
std::string fold_to_ascii(std::string_view text) {
    std::string out;
    std::size_t i = 0;
    while (i < text.size()) {
        const char32_t c = next_code_point(text, i);
        if (c < 0x80) {
            const auto ch = static_cast<unsigned char>(c);
            if (std::isalnum(ch)) out += static_cast<char>(std::tolower(ch));
            else if (ch == '\'' || ch == '`') out += '\'';
            else if (ch == ',' && !out.empty() && std::isdigit(static_cast<unsigned char>(out.back())) &&
                     i < text.size() && std::isdigit(static_cast<unsigned char>(text[i])))
                continue;  // thousands separator
            else out += ' ';
        } else if (c == 0x2018 || c == 0x2019 || c == 0x02BC || c == 0x00B4) {
            out += '\'';
        } else if (const char* folded = fold_latin(c)) {
            out += folded;
        } else {
            out += ' ';
        }
    }
    return out;
}

namespace {

const std::map<std::string, std::vector<std::string>>& irregular_contractions() {
    static const std::map<std::string, std::vector<std::string>> table = {
        {"won't", {"will", "not"}}, {"can't", {"can", "not"}}, {"cannot", {"can", "not"}},
        {"shan't", {"shall", "not"}}, {"ain't", {"is", "not"}}, {"let's", {"let", "us"}},
        {"y'all", {"you", "all"}}, {"o'clock", {"oclock"}}, {"ma'am", {"madam"}},
        {"'em", {"them"}}, {"'tis", {"it", "is"}}, {"gonna", {"going", "to"}},
        {"wanna", {"want", "to"}}, {"gotta", {"got", "to"}}};
    return table;
}

bool is_pronoun_is(const std::string& w) {
    static const std::array<const char*, 15> words = {"he", "she", "it", "that", "there", "what", "who", "where",
                                                      "here", "how", "this", "when", "why", "everyone", "nobody"};
    for (const char* p : words)
        if (w == p) return true;
    return false;
}

bool ends_with(const std::string& s, std::string_view suffix) {
    return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Step 4 for one word.
void expand_contraction(std::string w, std::vector<std::string>& out) {
    while (!w.empty() && w.front() == '\'') w.erase(w.begin());
    while (!w.empty() && w.back() == '\'') w.pop_back();
    if (w.empty()) return;
    if (auto it = irregular_contractions().find(w); it != irregular_contractions().end()) {
        out.insert(out.end(), it->second.begin(), it->second.end());
        return;
    }
    auto emit = [&](std::string base, std::initializer_list<const char*> tail) {
        std::erase(base, '\'');
        if (!base.empty()) out.push_back(base);
        for (const char* t : tail) out.push_back(t);
    };
    if (ends_with(w, "n't")) return emit(w.substr(0, w.size() - 3), {"not"});
    if (ends_with(w, "'re")) return emit(w.substr(0, w.size() - 3), {"are"});
    if (ends_with(w, "'ve")) return emit(w.substr(0, w.size() - 3), {"have"});
    if (ends_with(w, "'ll")) return emit(w.substr(0, w.size() - 3), {"will"});
    if (ends_with(w, "'m")) return emit(w.substr(0, w.size() - 2), {"am"});
    if (ends_with(w, "'d")) return emit(w.substr(0, w.size() - 2), {"would"});
    if (ends_with(w, "'s")) {
        std::string base = w.substr(0, w.size() - 2);
        if (is_pronoun_is(base)) return emit(base, {"is"});
        return emit(base, {});  // possessive
    }
    emit(w, {});
}

// Step 5: number words to digits.
enum class NumberKind { Unit, Teen, Ten, Hundred, Scale };
struct NumberWord {
    NumberKind kind;
    long long value;
    bool ordinal;
};

std::optional<NumberWord> number_word(const std::string& w) {
    static const std::map<std::string, NumberWord> table = [] {
        std::map<std::string, NumberWord> t;
        const char* units[] = {"zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine"};
        const char* unit_ord[] = {"zeroth", "first", "second", "third", "fourth", "fifth",
                                  "sixth", "seventh", "eighth", "ninth"};
        for (int i = 0; i < 10; ++i) {
            t[units[i]] = {NumberKind::Unit, i, false};
            t[unit_ord[i]] = {NumberKind::Unit, i, true};
        }
        const char* teens[] = {"ten", "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen",
                               "seventeen", "eighteen", "nineteen"};
        const char* teen_ord[] = {"tenth", "eleventh", "twelfth", "thirteenth", "fourteenth", "fifteenth",
                                  "sixteenth", "seventeenth", "eighteenth", "nineteenth"};
        for (int i = 0; i < 10; ++i) {
            t[teens[i]] = {NumberKind::Teen, 10 + i, false};
            t[teen_ord[i]] = {NumberKind::Teen, 10 + i, true};
        }
        const char* tens[] = {"twenty", "thirty", "forty", "fifty", "sixty", "seventy", "eighty", "ninety"};
        const char* ten_ord[] = {"twentieth", "thirtieth", "fortieth", "fiftieth", "sixtieth", "seventieth",
                                 "eightieth", "ninetieth"};
        for (int i = 0; i < 8; ++i) {
            t[tens[i]] = {NumberKind::Ten, 20 + 10 * i, false};
            t[ten_ord[i]] = {NumberKind::Ten, 20 + 10 * i, true};
        }
        t["hundred"] = {NumberKind::Hundred, 100, false};
        t["hundredth"] = {NumberKind::Hundred, 100, true};
        t["thousand"] = {NumberKind::Scale, 1000, false};
        t["thousandth"] = {NumberKind::Scale, 1000, true};
        t["million"] = {NumberKind::Scale, 1000000, false};
        t["millionth"] = {NumberKind::Scale, 1000000, true};
        return t;
    }();
    if (auto it = table.find(w); it != table.end()) return it->second;
    return std::nullopt;
}

std::string ordinal_suffix(long long v) {
    const long long m100 = v % 100, m10 = v % 10;
    if (m100 >= 11 && m100 <= 13) return "th";
    return m10 == 1 ? "st" : m10 == 2 ? "nd" : m10 == 3 ? "rd" : "th";
}

std::vector<NormalizedWord> numbers_to_digits(const std::vector<std::string>& words) {
    std::vector<NormalizedWord> out;
    std::size_t i = 0;
    while (i < words.size()) {
        auto first = number_word(words[i]);
        if (!first) {
            out.push_back({words[i++], false});
            continue;
        }
        // One number: total (completed scales) + current (below 1000).
        long long total = 0, current = 0;
        std::optional<NumberKind> last;
        bool ordinal = false;
        while (i < words.size() && !ordinal) {
            std::size_t next = i;
            // "and" joins "hundred and five", nothing else.
            if (words[i] == "and" && last && (*last == NumberKind::Hundred || *last == NumberKind::Scale) &&
                i + 1 < words.size()) {
                auto after = number_word(words[i + 1]);
                if (!after || after->kind == NumberKind::Hundred || after->kind == NumberKind::Scale) break;
                next = i + 1;
            }
            auto w = number_word(words[next]);
            if (!w) break;
            bool fits = false;
            switch (w->kind) {
            case NumberKind::Unit:
                fits = !last || *last == NumberKind::Hundred || *last == NumberKind::Scale ||
                       (*last == NumberKind::Ten && current % 10 == 0);
                if (fits) current += w->value;
                break;
            case NumberKind::Teen:
            case NumberKind::Ten:
                fits = !last || *last == NumberKind::Hundred || *last == NumberKind::Scale;
                if (fits) current += w->value;
                break;
            case NumberKind::Hundred:
                fits = !last || (current > 0 && current < 100 && *last != NumberKind::Hundred);
                if (fits) current = (current == 0 ? 1 : current) * 100;
                break;
            case NumberKind::Scale:
                fits = (!last || current > 0) && (total == 0 || total >= w->value * 1000);
                if (fits) {
                    total += (current == 0 ? 1 : current) * w->value;
                    current = 0;
                }
                break;
            }
            if (!fits) break;
            last = w->kind;
            ordinal = w->ordinal;
            i = next + 1;
        }
        const long long value = total + current;
        out.push_back({std::to_string(value) + (ordinal ? ordinal_suffix(value) : ""), true});
    }
    return out;
}

// ---------------------------------------------------------------- other languages

void append_utf8(std::string& out, char32_t c) {
    if (c < 0x80) {
        out += static_cast<char>(c);
    } else if (c < 0x800) {
        out += static_cast<char>(0xC0 | (c >> 6));
        out += static_cast<char>(0x80 | (c & 0x3F));
    } else if (c < 0x10000) {
        out += static_cast<char>(0xE0 | (c >> 12));
        out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (c & 0x3F));
    } else {
        out += static_cast<char>(0xF0 | (c >> 18));
        out += static_cast<char>(0x80 | ((c >> 12) & 0x3F));
        out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (c & 0x3F));
    }
}

// The letters a language keeps (step 1), each upper- or lower-case code
// point mapped to its lower-case form.
const std::map<char32_t, char32_t>* kept_letters(std::string_view language) {
    static const std::map<char32_t, char32_t> swedish = {{U'Å', U'å'}, {U'å', U'å'}, {U'Ä', U'ä'}, {U'ä', U'ä'},
                                                         {U'Ö', U'ö'}, {U'ö', U'ö'}, {U'É', U'é'}, {U'é', U'é'}};
    static const std::map<char32_t, char32_t> german = {{U'Ä', U'ä'}, {U'ä', U'ä'}, {U'Ö', U'ö'}, {U'ö', U'ö'},
                                                        {U'Ü', U'ü'}, {U'ü', U'ü'}, {U'ß', U'ß'}, {U'ẞ', U'ß'}};
    if (language == "sv") return &swedish;
    if (language == "de") return &german;
    return nullptr;
}

// Steps 1-3 for a language other than English: the words, lower case, the
// language's letters kept, apostrophes dropped.
std::vector<std::string> split_words_keeping(std::string_view text, const std::map<char32_t, char32_t>& kept) {
    std::vector<std::string> words;
    std::string w;
    auto flush = [&] {
        if (!w.empty()) words.push_back(std::move(w));
        w.clear();
    };
    std::size_t i = 0;
    while (i < text.size()) {
        const char32_t c = next_code_point(text, i);
        if (c < 0x80 && std::isalnum(static_cast<unsigned char>(c))) {
            w += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        } else if (c == '\'' || c == '`' || c == 0x2018 || c == 0x2019 || c == 0x02BC || c == 0x00B4) {
            continue;  // dropped: "geht's" -> "gehts"
        } else if (auto k = kept.find(c); k != kept.end()) {
            append_utf8(w, k->second);
        } else if (const char* folded = fold_latin(c)) {
            w += folded;
        } else {
            flush();
        }
    }
    flush();
    return words;
}

bool all_letters(const std::string& w) {
    return !w.empty() && !std::isdigit(static_cast<unsigned char>(w.front()));
}

// Step 5 for Swedish and German: the longest run of words (at most 6) whose
// concatenation is a number becomes its digits.
std::vector<NormalizedWord> language_numbers_to_digits(const std::vector<std::string>& words,
                                                       const detail::NumberGrammar& grammar) {
    constexpr std::size_t kLongestRun = 6;
    std::vector<NormalizedWord> out;
    std::size_t i = 0;
    while (i < words.size()) {
        std::size_t taken = 0;
        long long value = 0;
        std::string joined;
        for (std::size_t n = 1; n <= kLongestRun && i + n <= words.size() && all_letters(words[i + n - 1]); ++n) {
            joined += words[i + n - 1];
            if (n == 1 && std::find(grammar.alone_not_numbers.begin(), grammar.alone_not_numbers.end(), joined) !=
                              grammar.alone_not_numbers.end())
                continue;
            if (auto v = detail::parse_number_word(joined, grammar)) {
                taken = n;
                value = *v;
            }
        }
        if (taken == 0) {
            out.push_back({words[i++], false});
            continue;
        }
        out.push_back({std::to_string(value), true});
        i += taken;
    }
    return out;
}

}  // namespace

std::vector<NormalizedWord> normalize_tokens(std::string_view text, std::string_view language) {
    const auto* kept = kept_letters(language);
    const auto* grammar = detail::number_grammar_of(language);
    if (!kept || !grammar) return normalize_tokens(text);
    return language_numbers_to_digits(split_words_keeping(text, *kept), *grammar);
}

std::optional<std::vector<std::string>> words_keeping_letters(std::string_view text, std::string_view language) {
    const auto* kept = kept_letters(language);
    if (!kept) return std::nullopt;
    return split_words_keeping(text, *kept);
}

std::vector<std::string> normalize_words(std::string_view text, std::string_view language) {
    std::vector<std::string> out;
    for (auto& t : normalize_tokens(text, language)) out.push_back(std::move(t.text));
    return out;
}

std::string ascii_spelling(std::string_view word, std::string_view language) {
    static const std::map<std::string, const char*, std::less<>> german = {
        {"ä", "ae"}, {"ö", "oe"}, {"ü", "ue"}, {"ß", "ss"}};
    static const std::map<std::string, const char*, std::less<>> swedish = {{"é", "e"}};
    const auto* table = language == "de" ? &german : language == "sv" ? &swedish : nullptr;
    if (!table) return std::string(word);
    std::string out;
    for (std::size_t i = 0; i < word.size();) {
        const std::size_t start = i;
        next_code_point(word, i);
        const std::string_view letter = word.substr(start, i - start);
        const auto it = table->find(letter);
        if (it != table->end()) out += it->second;
        else out += letter;
    }
    return out;
}

std::vector<NormalizedWord> normalize_tokens(std::string_view text) {
    const std::string ascii = fold_to_ascii(text);
    std::vector<std::string> words;
    std::string w;
    for (char c : ascii) {
        if (c == ' ') {
            if (!w.empty()) expand_contraction(std::move(w), words);
            w.clear();
        } else {
            w += c;
        }
    }
    if (!w.empty()) expand_contraction(std::move(w), words);
    return numbers_to_digits(words);
}

std::vector<std::string> normalize_words(std::string_view text) {
    std::vector<std::string> out;
    for (auto& t : normalize_tokens(text)) out.push_back(std::move(t.text));
    return out;
}

std::string normalize_text(std::string_view text) {
    std::string out;
    for (const auto& w : normalize_words(text)) {
        if (!out.empty()) out += ' ';
        out += w;
    }
    return out;
}

}  // namespace avsi::analysis
