// Time-aligned label files: Praat TextGrid (long and short text formats, as
// described in Praat's "TextGrid file formats" manual page), HTK .lab (times in
// 100 ns units) and TSV, and their conversion to phone sequences.
#include "avsi/core/labels.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/checks.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"

namespace avsi {

namespace {

void append_utf8(std::string& out, char32_t cp) {
    if (cp < 0x80) {
        out += static_cast<char>(cp);
    } else if (cp < 0x800) {
        out += static_cast<char>(0xC0 | (cp >> 6));
        out += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
        out += static_cast<char>(0xE0 | (cp >> 12));
        out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
        out += static_cast<char>(0xF0 | (cp >> 18));
        out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
        out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (cp & 0x3F));
    }
}

// Decodes UTF-16 (after its BOM) to UTF-8, counting lines for error messages.
std::string utf16_to_utf8(std::string_view bytes, bool big_endian, const std::string& path) {
    if (bytes.size() % 2 != 0)
        throw InputError(path, 0, 0, "", "expected UTF-16 text (an even number of bytes), got an odd length");
    std::string out;
    out.reserve(bytes.size() / 2);
    int line = 1;
    auto unit = [&](std::size_t i) -> char32_t {
        const auto a = static_cast<unsigned char>(bytes[i]);
        const auto b = static_cast<unsigned char>(bytes[i + 1]);
        return big_endian ? (char32_t(a) << 8 | b) : (char32_t(b) << 8 | a);
    };
    for (std::size_t i = 0; i < bytes.size(); i += 2) {
        char32_t cp = unit(i);
        if (cp >= 0xD800 && cp <= 0xDBFF) {
            if (i + 3 >= bytes.size() || unit(i + 2) < 0xDC00 || unit(i + 2) > 0xDFFF)
                throw InputError(path, line, 0, "", "expected a UTF-16 low surrogate after a high surrogate");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (unit(i + 2) - 0xDC00);
            i += 2;
        } else if (cp >= 0xDC00 && cp <= 0xDFFF) {
            throw InputError(path, line, 0, "", "unexpected UTF-16 low surrogate");
        }
        if (cp == '\n') ++line;
        append_utf8(out, cp);
    }
    return out;
}

// Reads a text file as UTF-8, converting UTF-16 (with BOM) and dropping a UTF-8 BOM.
std::string read_unicode_text(const std::filesystem::path& path) {
    std::string bytes = read_text_file(path);
    if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
        static_cast<unsigned char>(bytes[1]) == 0xFE)
        return utf16_to_utf8(std::string_view(bytes).substr(2), false, path.string());
    if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0xFE &&
        static_cast<unsigned char>(bytes[1]) == 0xFF)
        return utf16_to_utf8(std::string_view(bytes).substr(2), true, path.string());
    if (bytes.size() >= 3 && bytes.compare(0, 3, "\xEF\xBB\xBF") == 0) bytes.erase(0, 3);
    return bytes;
}

// ---------------------------------------------------------------------------
// TextGrid tokens. Both Praat text formats are the same sequence of values
// (numbers, "strings", <flags>); the long format adds "key =" labels and
// "item [n]:" headings, which are checked when present.

enum class TokenKind { Number, String, Flag };

struct Token {
    TokenKind kind;
    std::string text;
    int line = 0;
    std::string key;  // the last keyword before the value (long format), or ""
};

const std::set<std::string, std::less<>> k_textgrid_keywords = {
    "File", "type", "Object", "class", "xmin", "xmax", "tiers", "size", "item",
    "intervals", "points", "text", "mark", "number", "time", "name"};

std::vector<Token> tokenize_textgrid(const std::string& text, const std::string& path) {
    std::vector<Token> tokens;
    std::string key;
    int line = 1;
    std::size_t i = 0;
    const std::size_t n = text.size();
    while (i < n) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
            ++i;
        } else if (std::isspace(static_cast<unsigned char>(c)) || c == '=' || c == ':') {
            ++i;
        } else if (c == '!') {  // comment to the end of the line
            while (i < n && text[i] != '\n') ++i;
        } else if (c == '"') {
            const int start_line = line;
            std::string value;
            ++i;
            for (;;) {
                if (i >= n)
                    throw InputError(path, start_line, 0, "",
                                     "expected a closing '\"' for the string, got end of file");
                if (text[i] == '"') {
                    if (i + 1 < n && text[i + 1] == '"') {
                        value += '"';
                        i += 2;
                        continue;
                    }
                    ++i;
                    break;
                }
                if (text[i] == '\n') ++line;
                value += text[i++];
            }
            tokens.push_back({TokenKind::String, std::move(value), start_line, key});
            key.clear();
        } else if (c == '<') {
            const std::size_t close = text.find('>', i);
            const std::size_t eol = text.find('\n', i);
            if (close == std::string::npos || close > eol)
                throw InputError(path, line, 0, "", "expected a flag such as <exists>, got an unclosed '<'");
            tokens.push_back({TokenKind::Flag, text.substr(i + 1, close - i - 1), line, key});
            key.clear();
            i = close + 1;
        } else if (c == '[') {  // "item [3]:" — an index heading, not a value
            const std::size_t close = text.find(']', i);
            const std::size_t eol = text.find('\n', i);
            if (close == std::string::npos || close > eol)
                throw InputError(path, line, 0, "", "expected ']' to close an index such as [1], got end of line");
            const std::string inside = text.substr(i + 1, close - i - 1);
            if (!inside.empty() && !parse_int(inside))
                throw InputError(path, line, 0, "", fmt::format("expected an index such as [1], got [{}]", inside));
            i = close + 1;
        } else if (std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.') {
            std::size_t j = i;
            while (j < n && !std::isspace(static_cast<unsigned char>(text[j]))) ++j;
            std::string word = text.substr(i, j - i);
            if (!parse_double(word))
                throw InputError(path, line, 0, key, fmt::format("expected a number, got \"{}\"", word));
            tokens.push_back({TokenKind::Number, std::move(word), line, key});
            key.clear();
            i = j;
        } else {
            std::size_t j = i;
            while (j < n && !std::isspace(static_cast<unsigned char>(text[j])) && text[j] != '=' &&
                   text[j] != '"' && text[j] != '[' && text[j] != ':' && text[j] != '?')
                ++j;
            std::string word = text.substr(i, j - i);
            if (word.empty()) {  // a lone '?' as in "tiers? <exists>"
                ++i;
                continue;
            }
            if (!k_textgrid_keywords.count(word)) {
                const std::string close = closest_match(
                    word, std::vector<std::string>(k_textgrid_keywords.begin(), k_textgrid_keywords.end()));
                throw InputError(path, line, 0, "",
                                 fmt::format("expected a number, a \"string\" or a TextGrid keyword, got "
                                             "\"{}\"{}",
                                             excerpt(word), close.empty() ? "" : fmt::format(" (did you mean '{}'?)", close)));
            }
            key = word;
            i = j;
        }
    }
    return tokens;
}

// Reads values from the token list in the order both formats share.
class TextGridParser {
public:
    TextGridParser(std::vector<Token> tokens, std::string path, int last_line)
        : m_tokens(std::move(tokens)), m_path(std::move(path)), m_last_line(last_line) {}

    TextGrid parse() {
        const Token& type = next_string("type", "the file type \"ooTextFile\"");
        if (type.text != "ooTextFile" && type.text != "ooTextFile short")
            fail(type, "File type", fmt::format("expected \"ooTextFile\" (a Praat text file), got \"{}\"", type.text));
        const Token& cls = next_string("class", "the object class \"TextGrid\"");
        if (cls.text != "TextGrid")
            fail(cls, "Object class", fmt::format("expected \"TextGrid\", got \"{}\"", cls.text));

        TextGrid grid;
        grid.start_s = next_number("xmin", "xmin");
        grid.end_s = next_number("xmax", "xmax");
        if (grid.end_s < grid.start_s)
            fail(previous(), "xmax", fmt::format("expected xmax >= xmin ({}), got {}", grid.start_s, grid.end_s));
        std::size_t tier_count = 0;
        if (m_pos < m_tokens.size() && m_tokens[m_pos].kind == TokenKind::Flag) {
            const Token& flag = m_tokens[m_pos++];
            if (flag.text == "exists") tier_count = next_count("size", "size (number of tiers)");
            else if (flag.text != "absent")
                fail(flag, "tiers", fmt::format("expected <exists> or <absent>, got <{}>", flag.text));
        } else {
            tier_count = next_count("size", "size (number of tiers)");
        }
        for (std::size_t t = 0; t < tier_count; ++t) grid.tiers.push_back(parse_tier(grid, t + 1));
        if (m_pos < m_tokens.size())
            fail(m_tokens[m_pos], "",
                 fmt::format("expected the end of the file after {} tiers, got \"{}\"", tier_count,
                             m_tokens[m_pos].text));
        return grid;
    }

private:
    Tier parse_tier(const TextGrid& grid, std::size_t number) {
        Tier tier;
        const std::string what = fmt::format("tier {}", number);
        const Token& cls = next_string("class", what + " class");
        if (cls.text == "IntervalTier") tier.is_interval = true;
        else if (cls.text == "TextTier") tier.is_interval = false;
        else fail(cls, what + " class", fmt::format("expected \"IntervalTier\" or \"TextTier\", got \"{}\"", cls.text));
        tier.name = next_string("name", what + " name").text;
        const std::string where = fmt::format("tier '{}'", tier.name);
        tier.start_s = next_number("xmin", where + " xmin");
        tier.end_s = next_number("xmax", where + " xmax");
        if (tier.end_s < tier.start_s)
            fail(previous(), where + " xmax", fmt::format("expected xmax >= xmin ({}), got {}", tier.start_s, tier.end_s));
        (void)grid;
        const std::size_t count = next_count("size", where + " size");
        double previous_end = tier.start_s;
        for (std::size_t k = 0; k < count; ++k) {
            Interval item;
            if (tier.is_interval) {
                const std::string iw = fmt::format("{} interval {}", where, k + 1);
                item.start_s = next_number("xmin", iw + " xmin");
                const int start_line = previous().line;
                item.end_s = next_number("xmax", iw + " xmax");
                if (item.end_s < item.start_s)
                    fail(previous(), iw + " xmax",
                         fmt::format("expected xmax >= xmin ({}), got {}", item.start_s, item.end_s));
                if (item.start_s < previous_end - 1e-9)
                    fail_line(start_line, iw + " xmin",
                              fmt::format("expected a start at or after the previous interval's end ({}), got {}",
                                          previous_end, item.start_s));
                const Token& text = next_string("text", iw + " text");
                item.text = text.text;
                item.line = text.line;
                previous_end = item.end_s;
            } else {
                const std::string pw = fmt::format("{} point {}", where, k + 1);
                item.start_s = next_number("number", pw + " time", "time");
                item.end_s = item.start_s;
                if (item.start_s < previous_end - 1e-9 && k > 0)
                    fail(previous(), pw + " time",
                         fmt::format("expected a time at or after the previous point ({}), got {}",
                                     previous_end, item.start_s));
                const Token& mark = next_string("mark", pw + " mark");
                item.text = mark.text;
                item.line = mark.line;
                previous_end = item.start_s;
            }
            tier.items.push_back(std::move(item));
        }
        return tier;
    }

    const Token& previous() const { return m_tokens[m_pos - 1]; }

    [[noreturn]] void fail(const Token& token, const std::string& field, const std::string& message) const {
        throw InputError(m_path, token.line, 0, field, message);
    }
    [[noreturn]] void fail_line(int line, const std::string& field, const std::string& message) const {
        throw InputError(m_path, line, 0, field, message);
    }

    const Token& next(const std::string& what) {
        if (m_pos >= m_tokens.size())
            throw InputError(m_path, m_last_line, 0, what,
                             "expected a value, got the end of the file (truncated TextGrid?)");
        return m_tokens[m_pos++];
    }

    void check_key(const Token& token, const std::string& what, std::string_view key,
                   std::string_view alt_key = {}) const {
        if (!token.key.empty() && token.key != key && (alt_key.empty() || token.key != alt_key))
            fail(token, what, fmt::format("expected the key '{}', got '{}'", key, token.key));
    }

    const Token& next_string(std::string_view key, const std::string& what) {
        const Token& token = next(what);
        if (token.kind != TokenKind::String)
            fail(token, what, fmt::format("expected a \"string\", got {}", describe(token)));
        check_key(token, what, key);
        return token;
    }

    double next_number(std::string_view key, const std::string& what, std::string_view alt_key = {}) {
        const Token& token = next(what);
        if (token.kind != TokenKind::Number)
            fail(token, what, fmt::format("expected a number, got {}", describe(token)));
        check_key(token, what, key, alt_key);
        return *parse_double(token.text);
    }

    std::size_t next_count(std::string_view key, const std::string& what) {
        const Token& token = next(what);
        const auto value = token.kind == TokenKind::Number ? parse_int(token.text) : std::nullopt;
        if (!value || *value < 0)
            fail(token, what, fmt::format("expected a count (an integer >= 0), got {}", describe(token)));
        check_key(token, what, key);
        return static_cast<std::size_t>(*value);
    }

    static std::string describe(const Token& token) {
        switch (token.kind) {
            case TokenKind::Number: return fmt::format("the number {}", token.text);
            case TokenKind::String: return fmt::format("the string \"{}\"", token.text);
            case TokenKind::Flag: return fmt::format("<{}>", token.text);
        }
        return token.text;
    }

    std::vector<Token> m_tokens;
    std::string m_path;
    int m_last_line;
    std::size_t m_pos = 0;
};

std::string textgrid_string(const std::string& text) {
    std::string out = "\"";
    for (char c : text) {
        if (c == '"') out += '"';
        out += c;
    }
    out += '"';
    return out;
}

// Splits a label-file line into fields: on tabs if it has any, else on spaces.
std::vector<std::string> split_fields(const std::string& line) {
    std::vector<std::string> fields;
    if (line.find('\t') != std::string::npos) {
        std::size_t start = 0;
        for (;;) {
            const std::size_t tab = line.find('\t', start);
            fields.push_back(trim(line.substr(start, tab == std::string::npos ? std::string::npos : tab - start)));
            if (tab == std::string::npos) break;
            start = tab + 1;
        }
        return fields;
    }
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
        std::size_t j = i;
        while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
        if (j > i) fields.push_back(line.substr(i, j - i));
        i = j;
    }
    return fields;
}

// Calls `fn(line_number, line)` for each line, without the line end.
template <typename Fn>
void for_each_line(const std::string& text, Fn fn) {
    std::size_t pos = 0;
    int number = 0;
    while (pos < text.size()) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(pos, end - pos);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        fn(++number, line);
        pos = end + 1;
    }
}

}  // namespace

const Tier& TextGrid::tier(const std::string& name, const std::string& path) const {
    for (const auto& t : tiers)
        if (t.name == name) return t;
    std::vector<std::string> names;
    std::string list;
    for (const auto& t : tiers) {
        names.push_back(t.name);
        list += (list.empty() ? "'" : ", '") + t.name + "'";
    }
    const std::string close = closest_match(name, names);
    throw InputError(path, 0, 0, "tier",
                     fmt::format("expected a tier named '{}', got tiers: {}{}", name,
                                 list.empty() ? "(none)" : list,
                                 close.empty() ? "" : fmt::format(" (did you mean '{}'?)", close)));
}

TextGrid read_textgrid(const std::filesystem::path& path) {
    const std::string text = read_unicode_text(path);
    if (text.rfind("ooBinaryFile", 0) == 0)
        throw InputError(path.string(), 1, 0, "",
                         "expected a Praat text file, got a binary TextGrid (save it as text in Praat)");
    const int last_line = static_cast<int>(std::count(text.begin(), text.end(), '\n')) +
                          (text.empty() || text.back() == '\n' ? 0 : 1);
    TextGridParser parser(tokenize_textgrid(text, path.string()), path.string(), std::max(1, last_line));
    return parser.parse();
}

void write_textgrid(const std::filesystem::path& path, const TextGrid& grid) {
    std::string out;
    out += "File type = \"ooTextFile\"\nObject class = \"TextGrid\"\n\n";
    out += fmt::format("xmin = {} \nxmax = {} \n", grid.start_s, grid.end_s);
    if (grid.tiers.empty()) {
        out += "tiers? <absent> \n";
    } else {
        out += fmt::format("tiers? <exists> \nsize = {} \nitem []: \n", grid.tiers.size());
    }
    for (std::size_t t = 0; t < grid.tiers.size(); ++t) {
        const Tier& tier = grid.tiers[t];
        out += fmt::format("    item [{}]:\n", t + 1);
        out += fmt::format("        class = \"{}\" \n", tier.is_interval ? "IntervalTier" : "TextTier");
        out += fmt::format("        name = {} \n", textgrid_string(tier.name));
        out += fmt::format("        xmin = {} \n        xmax = {} \n", tier.start_s, tier.end_s);
        const char* items = tier.is_interval ? "intervals" : "points";
        out += fmt::format("        {}: size = {} \n", items, tier.items.size());
        for (std::size_t k = 0; k < tier.items.size(); ++k) {
            const Interval& item = tier.items[k];
            out += fmt::format("        {} [{}]:\n", items, k + 1);
            if (tier.is_interval) {
                out += fmt::format("            xmin = {} \n            xmax = {} \n", item.start_s, item.end_s);
                out += fmt::format("            text = {} \n", textgrid_string(item.text));
            } else {
                out += fmt::format("            number = {} \n", item.start_s);
                out += fmt::format("            mark = {} \n", textgrid_string(item.text));
            }
        }
    }
    write_text_file(path, out);
}

std::vector<Interval> read_htk_lab(const std::filesystem::path& path, LabTimeUnit unit, LabTimeUnit* used_unit) {
    const std::string text = read_unicode_text(path);
    const std::string p = path.string();
    struct Row {
        int line;
        std::vector<std::string> fields;
    };
    std::vector<Row> rows;
    bool decimal = false;
    for_each_line(text, [&](int number, const std::string& line) {
        auto fields = split_fields(line);
        if (fields.empty()) return;
        if (fields.size() < 3) {
            if (fields.size() == 1 && hts_centre_phone(fields[0]))
                throw InputError(p, number, 1, "",
                                 "expected \"start end label\", got an HTS full-context label without times (a "
                                 "front end's training label; align it first, e.g. with HSMMAlign, for timed labels)");
            throw InputError(p, number, 0, "",
                             fmt::format("expected \"start end label\" (times in 100 ns units), got \"{}\"", trim(line)));
        }
        for (std::size_t f = 0; f < 2; ++f)
            if (fields[f].find_first_of(".eE") != std::string::npos && parse_double(fields[f])) decimal = true;
        rows.push_back({number, std::move(fields)});
    });
    if (unit == LabTimeUnit::Auto) unit = decimal ? LabTimeUnit::Seconds : LabTimeUnit::HundredNanoseconds;
    if (used_unit) *used_unit = unit;
    const bool seconds = unit == LabTimeUnit::Seconds;
    const char* unit_text = seconds ? "a time in seconds" : "a time in 100 ns units";
    std::vector<Interval> intervals;
    for (const Row& row : rows) {
        const auto& fields = row.fields;
        double start_s = 0.0, end_s = 0.0;
        if (seconds) {
            const auto start = parse_double(fields[0]);
            const auto end = parse_double(fields[1]);
            if (!start || !std::isfinite(*start) || *start < 0)
                throw InputError(p, row.line, 1, "start",
                                 fmt::format("expected {} (a number >= 0), got \"{}\"", unit_text, fields[0]));
            if (!end || !std::isfinite(*end) || *end < *start)
                throw InputError(p, row.line, 0, "end",
                                 fmt::format("expected {} (>= start {}), got \"{}\"", unit_text, *start, fields[1]));
            start_s = *start;
            end_s = *end;
        } else {
            const auto start = parse_int(fields[0]);
            const auto end = parse_int(fields[1]);
            if (!start || *start < 0)
                throw InputError(p, row.line, 1, "start",
                                 fmt::format("expected {} (an integer >= 0), got \"{}\"", unit_text, fields[0]));
            if (!end || *end < *start)
                throw InputError(p, row.line, 0, "end",
                                 fmt::format("expected {} (an integer >= start {}), got \"{}\"", unit_text, *start,
                                             fields[1]));
            start_s = static_cast<double>(*start) * 1e-7;
            end_s = static_cast<double>(*end) * 1e-7;
        }
        // Trailing fields: HTK scores; HSMMAlign writes the phone's label after its first state's.
        const bool state_line = fields[2].size() > 3 && fields[2].back() == ']';
        for (std::size_t f = 3; f < fields.size(); ++f)
            if (!parse_double(fields[f]) && !(state_line && f == 3))
                throw InputError(p, row.line, 0, "score",
                                 fmt::format("expected a numeric score after the label, got \"{}\"", fields[f]));
        intervals.push_back({start_s, end_s, fields[2], row.line});
    }
    return intervals;
}

std::vector<Interval> read_timit_phn(const std::filesystem::path& path, double sample_rate_hz) {
    const std::string text = read_unicode_text(path);
    const std::string p = path.string();
    if (!(sample_rate_hz > 0.0) || !std::isfinite(sample_rate_hz))
        throw InputError(p, 0, 0, "sample rate", fmt::format("expected a sample rate > 0 Hz, got {}", sample_rate_hz));
    std::vector<Interval> intervals;
    for_each_line(text, [&](int number, const std::string& line) {
        const auto fields = split_fields(line);
        if (fields.empty()) return;
        if (fields.size() != 3)
            throw InputError(p, number, 0, "",
                             fmt::format("expected \"start end phone\" (sample indices at {} Hz), got \"{}\"",
                                         sample_rate_hz, trim(line)));
        const auto start = parse_int(fields[0]);
        const auto end = parse_int(fields[1]);
        if (!start || *start < 0)
            throw InputError(p, number, 1, "start",
                             fmt::format("expected a sample index (an integer >= 0), got \"{}\"", fields[0]));
        if (!end || *end < *start)
            throw InputError(p, number, 0, "end",
                             fmt::format("expected a sample index (an integer >= start {}), got \"{}\"", *start,
                                         fields[1]));
        intervals.push_back({static_cast<double>(*start) / sample_rate_hz, static_cast<double>(*end) / sample_rate_hz,
                             fields[2], number});
    });
    return intervals;
}

std::vector<Interval> read_label_tsv(const std::filesystem::path& path) {
    const std::string text = read_unicode_text(path);
    const std::string p = path.string();
    std::vector<Interval> intervals;
    bool first = true;
    for_each_line(text, [&](int number, const std::string& line) {
        const std::string trimmed = trim(line);
        if (trimmed.empty() || trimmed[0] == '#') return;
        const auto fields = split_fields(line);
        const bool is_first = first;
        first = false;
        if (is_first && fields.size() >= 2 && !parse_double(fields[0]) && !parse_double(fields[1]))
            return;  // header line, e.g. "start_s end_s phone"
        if (fields.size() != 3)
            throw InputError(p, number, 0, "",
                             fmt::format("expected 3 fields \"start_s end_s label\", got {}", fields.size()));
        const auto start = parse_double(fields[0]);
        const auto end = parse_double(fields[1]);
        if (!start || *start < 0)
            throw InputError(p, number, 1, "start_s",
                             fmt::format("expected a time in seconds >= 0, got \"{}\"", fields[0]));
        if (!end || *end < *start)
            throw InputError(p, number, 0, "end_s",
                             fmt::format("expected a time in seconds >= start_s ({}), got \"{}\"", *start, fields[1]));
        intervals.push_back({*start, *end, fields[2], number});
    });
    return intervals;
}

std::optional<LabelPhoneSet> parse_label_phone_set(std::string_view name) {
    if (name == "auto") return LabelPhoneSet::Auto;
    if (name == "arpabet") return LabelPhoneSet::Arpabet;
    if (name == "festival") return LabelPhoneSet::Festival;
    if (name == "timit") return LabelPhoneSet::Timit;
    if (name == "mocha") return LabelPhoneSet::Mocha;
    return std::nullopt;
}

std::optional<HtsPhone> hts_centre_phone(std::string_view label) {
    // p1^p2-p3+p4=p5@… : the centre phone p3 lies between the first '-' after
    // '^' and the next '+', which is followed by '='.
    const std::size_t caret = label.find('^');
    if (caret == std::string_view::npos) return std::nullopt;
    const std::size_t minus = label.find('-', caret + 1);
    if (minus == std::string_view::npos) return std::nullopt;
    const std::size_t plus = label.find('+', minus + 1);
    if (plus == std::string_view::npos) return std::nullopt;
    const std::size_t equals = label.find('=', plus + 1);
    if (equals == std::string_view::npos || plus == minus + 1) return std::nullopt;
    HtsPhone out;
    out.phone = std::string(label.substr(minus + 1, plus - minus - 1));
    // The five phones come before the first '@' or '/' (p5@…/A:…).
    if (out.phone.find_first_of("^=@/:") != std::string::npos ||
        equals > std::min(label.find('@'), label.find('/')))
        return std::nullopt;
    // "/B:b1-b2-b3…": b1 says whether the current syllable is stressed.
    const std::size_t b = label.find("/B:");
    if (b != std::string_view::npos) {
        const std::size_t stop = label.find_first_of("-@&#$!;|/", b + 3);
        const std::string_view b1 = label.substr(b + 3, stop == std::string_view::npos ? std::string_view::npos
                                                                                         : stop - b - 3);
        if (b1 == "1") out.stressed = true;
        else if (b1 == "0") out.stressed = false;
    }
    return out;
}

std::vector<Interval> merge_hts_labels(const std::vector<Interval>& intervals, const std::string& source_path) {
    std::vector<Interval> out;
    int last_state = 0;          // state of the last merged line (0: none)
    std::string last_label;      // its label without the state suffix
    for (const Interval& in : intervals) {
        Interval iv = in;
        int state = 0;
        // A state suffix "[n]", n = 2…9 (HTS numbers the emitting states from 2).
        if (iv.text.size() > 3 && iv.text.back() == ']') {
            const std::size_t open = iv.text.rfind('[');
            const auto n = open == std::string::npos ? std::nullopt
                                                     : parse_int(iv.text.substr(open + 1, iv.text.size() - open - 2));
            if (!n || *n < 2 || *n > 9)
                throw InputError(source_path, iv.line, 0, "state",
                                 fmt::format("expected a state suffix [2] … [9] at the end of an HTS state-aligned "
                                             "label, got \"{}\"",
                                             iv.text.substr(open == std::string::npos ? 0 : open)));
            state = static_cast<int>(*n);
            iv.text.erase(open);
        }
        if (state > 0 && state > last_state && !out.empty() && iv.text == last_label &&
            std::abs(iv.start_s - out.back().end_s) < 1e-6) {
            out.back().end_s = iv.end_s;  // the next state of the same phone
            last_state = state;
            continue;
        }
        if (state > 2 && !(state > last_state && iv.text == last_label))
            throw InputError(source_path, iv.line, 0, "state",
                             fmt::format("expected state [2] to start a phone (or state [{}] of \"{}\"), got state "
                                         "[{}]",
                                         last_state + 1, hts_centre_phone(last_label) ? hts_centre_phone(last_label)->phone
                                                                                       : last_label,
                                         state));
        last_state = state;
        last_label = iv.text;
        out.push_back(std::move(iv));
    }
    for (Interval& iv : out) {
        if (iv.text.find('^') == std::string::npos) continue;
        const auto centre = hts_centre_phone(iv.text);
        if (!centre)
            throw InputError(source_path, iv.line, 0, "label",
                             fmt::format("expected an HTS full-context label \"p1^p2-p3+p4=p5…\" (the centre phone "
                                         "p3 between '-' and '+'), got \"{}\"",
                                         iv.text.substr(0, 60)));
        iv.text = centre->phone;
        // The syllable's stress as a digit on a vowel, as ARPAbet writes it ("ae1").
        if (centre->stressed) {
            const PhoneInventory& inventory = PhoneInventory::builtin();
            bool vowel = false;
            try {
                const auto phones = inventory.from_festival(centre->phone, false, "");
                vowel = !phones.empty() && inventory.is_vowel(phones.front().symbol);
            } catch (const InputError&) {
                try {
                    vowel = inventory.is_vowel(inventory.parse_label(centre->phone, "").symbol);
                } catch (const InputError&) {
                }
            }
            if (vowel && !std::isdigit(static_cast<unsigned char>(iv.text.back())))
                iv.text += *centre->stressed ? '1' : '0';
        }
    }
    return out;
}

namespace {

struct UnitGuess {
    std::string name;
    std::string advice;
    double seconds_per_unit;
};

// Units label times are commonly written in.
const std::vector<UnitGuess>& common_units() {
    static const std::vector<UnitGuess> units = {
        {"100 ns units", "an HTK .lab", 1e-7},
        {"sample indices at 16000 Hz", "a TIMIT .phn", 1.0 / 16000.0},
        {"sample indices at 8000 Hz", "a .phn with --sample-rate 8000", 1.0 / 8000.0},
        {"sample indices at 22050 Hz", "a .phn with --sample-rate 22050", 1.0 / 22050.0},
        {"sample indices at 44100 Hz", "a .phn with --sample-rate 44100", 1.0 / 44100.0},
        {"sample indices at 48000 Hz", "a .phn with --sample-rate 48000", 1.0 / 48000.0},
        {"milliseconds", "convert them to seconds for a .tsv", 1e-3},
        {"seconds", "a .tsv or a MOCHA .lab", 1.0},
    };
    return units;
}

}  // namespace

void check_label_times(const std::vector<Interval>& intervals, const std::string& source_path,
                       const std::string& unit, double seconds_per_unit) {
    constexpr double min_phone_s = 0.005, min_utterance_s = 0.05;
    std::vector<double> durations;
    const Interval* first_short = nullptr;
    for (const Interval& iv : intervals) {
        const double d = iv.end_s - iv.start_s;
        if (!(d > 0.0)) continue;  // zero-length marks are not phones
        durations.push_back(d);
        if (d < min_phone_s && !first_short) first_short = &iv;
    }
    const double utterance_s = intervals.empty() ? 0.0 : intervals.back().end_s - intervals.front().start_s;
    if (durations.empty()) return;  // nothing timed: phones_from_intervals reports it
    if (!first_short && utterance_s >= min_utterance_s) return;
    // The unit that makes the median phone a typical 30–300 ms (closest to 80 ms).
    std::vector<double> sorted = durations;
    std::sort(sorted.begin(), sorted.end());
    const double median_units = sorted[sorted.size() / 2] / seconds_per_unit;
    // Every unit that makes the median phone a typical 30–300 ms, the common ones first.
    std::string hint;
    int shown = 0;
    for (const UnitGuess& u : common_units()) {
        const double median_s = median_units * u.seconds_per_unit;
        if (median_s < 0.03 || median_s > 0.3 || std::abs(u.seconds_per_unit / seconds_per_unit - 1.0) < 1e-9) continue;
        if (shown++ == 3) break;
        hint += fmt::format("{} {} (median phone {:.1f} ms: {})", shown == 1 ? "; the times look like" : " or",
                            u.name, median_s * 1e3, u.advice);
    }
    if (first_short)
        throw InputError(source_path, first_short->line, 0, fmt::format("label \"{}\"", first_short->text),
                         fmt::format("expected a phone of at least 5 ms, got {:.3g} ms with the times read as {}{}",
                                     (first_short->end_s - first_short->start_s) * 1e3, unit, hint));
    throw InputError(source_path, intervals.back().line, 0, "end",
                     fmt::format("expected an utterance of at least 50 ms, got {:.3g} ms with the times read as {}{}",
                                 utterance_s * 1e3, unit, hint));
}

namespace {

// The project phones of one label in one phone set; nullopt if the set does
// not know it (Auto: the ARPAbet, IPA, Festival and TIMIT tables in turn).
std::optional<std::vector<Phone>> map_label(const PhoneInventory& inventory, const std::string& label,
                                            LabelPhoneSet set) {
    auto attempt = [&](auto&& fn) -> std::optional<std::vector<Phone>> {
        try {
            return fn();
        } catch (const InputError&) {
            return std::nullopt;
        }
    };
    auto arpabet = [&] { return attempt([&] { return std::vector<Phone>{inventory.parse_label(label, "")}; }); };
    auto ipa = [&] { return attempt([&] { return inventory.from_ipa(label, ""); }); };
    // Festival's phones, a vowel perhaps with a stress digit ("ae1", from HTS labels).
    auto festival = [&] {
        return attempt([&] {
            const char last = label.empty() ? ' ' : label.back();
            if (label.size() > 1 && last >= '0' && last <= '2') {
                const std::string base = label.substr(0, label.size() - 1);
                auto phones = inventory.from_festival(base, last != '0', "");
                if (phones.empty() || !inventory.is_vowel(phones.front().symbol))
                    throw InputError("", 0, 0, "phone", "only vowels carry a stress digit");
                return phones;
            }
            return inventory.from_festival(label, false, "");
        });
    };
    auto timit = [&] { return attempt([&] { return inventory.from_timit(label, ""); }); };
    auto mocha = [&] { return attempt([&] { return inventory.from_mocha(label, ""); }); };
    switch (set) {
        case LabelPhoneSet::Arpabet:
            if (auto p = arpabet()) return p;
            return ipa();
        case LabelPhoneSet::Festival: return festival();
        case LabelPhoneSet::Timit: return timit();
        case LabelPhoneSet::Mocha: return mocha();
        case LabelPhoneSet::Auto:
            if (auto p = arpabet()) return p;
            if (auto p = ipa()) return p;
            if (auto p = festival()) return p;
            return timit();
    }
    return std::nullopt;
}

const char* phone_set_text(LabelPhoneSet set) {
    switch (set) {
        case LabelPhoneSet::Auto: return "an ARPAbet phone of the project set (AA1, P, sil), an IPA, Festival or TIMIT label";
        case LabelPhoneSet::Arpabet: return "an ARPAbet phone of the project set (AA1, P, sil) or an IPA label";
        case LabelPhoneSet::Festival: return "a phone of Festival's radio set (pau, ax, el)";
        case LabelPhoneSet::Timit: return "one of TIMIT's 61 symbols (h#, ix, bcl)";
        case LabelPhoneSet::Mocha: return "a symbol of MOCHA's set (sil, breath, @@, ii)";
    }
    return "";
}

// TIMIT: does the release `next` end the closure `closure` (bcl b, dcl d, …;
// also dcl jh and tcl ch, the closures of the affricates)?
bool closure_released_by(const std::string& closure, const std::string& next) {
    static const std::map<std::string, std::vector<std::string>> releases = {
        {"bcl", {"b"}}, {"dcl", {"d", "jh"}}, {"gcl", {"g"}}, {"pcl", {"p"}}, {"tcl", {"t", "ch"}}, {"kcl", {"k"}}};
    const auto it = releases.find(closure);
    return it != releases.end() && std::find(it->second.begin(), it->second.end(), next) != it->second.end();
}

}  // namespace

PhoneSequence phones_from_intervals(const std::vector<Interval>& input, const std::string& source_path,
                                    LabelPhoneSet phone_set) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    // A TIMIT closure followed at once by its release is one stop (or affricate).
    std::vector<Interval> intervals;
    for (std::size_t k = 0; k < input.size(); ++k) {
        const Interval& iv = input[k];
        const bool timit = phone_set == LabelPhoneSet::Timit || phone_set == LabelPhoneSet::Auto;
        if (timit && k + 1 < input.size() && closure_released_by(trim(iv.text), trim(input[k + 1].text)) &&
            std::abs(input[k + 1].start_s - iv.end_s) < 1e-6) {
            Interval merged = input[k + 1];
            merged.start_s = iv.start_s;
            merged.line = iv.line;
            intervals.push_back(std::move(merged));
            ++k;
            continue;
        }
        intervals.push_back(iv);
    }
    // Map every label; in Auto, a file some of whose labels only MOCHA knows is MOCHA's.
    std::vector<std::optional<std::vector<Phone>>> mapped(intervals.size());
    std::size_t first_unknown = intervals.size();
    for (std::size_t k = 0; k < intervals.size(); ++k) {
        mapped[k] = map_label(inventory, trim(intervals[k].text), phone_set);
        if (!mapped[k] && first_unknown == intervals.size()) first_unknown = k;
    }
    if (phone_set == LabelPhoneSet::Auto && first_unknown < intervals.size()) {
        std::vector<std::optional<std::vector<Phone>>> mocha(intervals.size());
        bool all = true;
        for (std::size_t k = 0; k < intervals.size() && all; ++k) {
            mocha[k] = map_label(inventory, trim(intervals[k].text), LabelPhoneSet::Mocha);
            all = mocha[k].has_value();
        }
        if (all) {
            log_info("{}: reading the labels in MOCHA-TIMIT's phone set (\"{}\" is MOCHA's)", source_path,
                     trim(intervals[first_unknown].text));
            mapped = std::move(mocha);
            first_unknown = intervals.size();
        }
    }
    if (first_unknown < intervals.size()) {
        const Interval& iv = intervals[first_unknown];
        throw InputError(source_path, iv.line, 0, fmt::format("interval {}", first_unknown + 1),
                         fmt::format("unknown phone label \"{}\": expected {} listed in protocols/languages/en/phone_map.tsv",
                                     excerpt(trim(iv.text)), phone_set_text(phone_set)));
    }

    PhoneSequence phones;
    auto push = [&phones](Phone phone) {
        if (!phones.empty() && phone.symbol == "sil" && phones.back().symbol == "sil") {
            phones.back().end_s = phone.end_s;
            return;
        }
        phones.push_back(std::move(phone));
    };
    double previous_end = 0.0;
    for (std::size_t k = 0; k < intervals.size(); ++k) {
        const Interval& iv = intervals[k];
        const std::string field = fmt::format("interval {}", k + 1);
        if (!(iv.start_s >= 0.0) || !(iv.end_s >= iv.start_s) || !std::isfinite(iv.end_s))
            throw InputError(source_path, iv.line, 0, field,
                             fmt::format("expected 0 <= start <= end, got {} .. {}", iv.start_s, iv.end_s));
        require_time_s(iv.end_s, at(source_path, iv.line, 0, field + " end"));
        if (iv.start_s < previous_end - 1e-6)
            throw InputError(source_path, iv.line, 0, field,
                             fmt::format("expected a start at or after the previous label's end ({}), got {}",
                                         previous_end, iv.start_s));
        const std::string label = trim(iv.text);
        if (iv.end_s <= iv.start_s) {
            log_debug("{}: skipping the zero-length label \"{}\" at {} s", source_path, label, iv.start_s);
            continue;
        }
        if (iv.start_s > previous_end + 1e-6) push({"sil", previous_end, iv.start_s, false});
        const std::vector<Phone>& ps = *mapped[k];
        if (ps.empty()) {
            // No phone of its own (TIMIT q): its time joins the phone before it.
            if (phones.empty()) push({"sil", iv.start_s, iv.end_s, false});
            else phones.back().end_s = iv.end_s;
            previous_end = iv.end_s;
            continue;
        }
        const double start = std::max(iv.start_s, phones.empty() ? 0.0 : phones.back().end_s);
        const double step = (iv.end_s - start) / static_cast<double>(ps.size());
        for (std::size_t m = 0; m < ps.size(); ++m) {
            Phone phone = ps[m];
            phone.start_s = start + step * static_cast<double>(m);
            phone.end_s = m + 1 == ps.size() ? iv.end_s : start + step * static_cast<double>(m + 1);
            push(std::move(phone));
        }
        previous_end = iv.end_s;
    }
    return phones;
}

PhoneSequence read_phones(const std::filesystem::path& path, const LabelReadOptions& options) {
    const std::string ext = ascii_lower(path.extension().string());
    std::vector<Interval> intervals;
    std::string unit = "seconds";
    double seconds_per_unit = 1.0;
    LabelPhoneSet set = options.phone_set;
    if (ext == ".textgrid") {
        const TextGrid grid = read_textgrid(path);
        const Tier& tier = grid.tier(options.tier, path.string());
        if (!tier.is_interval)
            throw InputError(path.string(), 0, 0, "tier",
                             fmt::format("expected '{}' to be an interval tier, got a point tier", options.tier));
        intervals = tier.items;
    } else if (ext == ".lab") {
        LabTimeUnit used = LabTimeUnit::Auto;
        intervals = read_htk_lab(path, options.lab_unit, &used);
        if (used == LabTimeUnit::HundredNanoseconds) {
            unit = "100 ns units (HTK)";
            seconds_per_unit = 1e-7;
        }
        intervals = merge_hts_labels(intervals, path.string());
    } else if (ext == ".phn") {
        intervals = read_timit_phn(path, options.sample_rate_hz);
        unit = fmt::format("sample indices at {} Hz", options.sample_rate_hz);
        seconds_per_unit = 1.0 / options.sample_rate_hz;
        if (set == LabelPhoneSet::Auto) set = LabelPhoneSet::Timit;
    } else if (ext == ".tsv") {
        intervals = read_label_tsv(path);
    } else {
        throw InputError(path, fmt::format("unsupported label file extension '{}'; supported extensions are "
                                           "'.TextGrid', '.lab', '.phn' and '.tsv'",
                                           path.extension().string()));
    }
    check_label_times(intervals, path.string(), unit, seconds_per_unit);
    PhoneSequence phones = phones_from_intervals(intervals, path.string(), set);
    if (phones.empty())
        throw InputError(path.string(), 0, 0, "phones",
                         intervals.empty() ? std::string("expected timed phones, got none (an empty file or tier)")
                                           : "expected timed phones, got only zero-length labels");
    return phones;
}

std::string phones_tsv(const PhoneSequence& phones) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::string out = "start_s\tend_s\tphone\n";
    for (const Phone& phone : phones)
        out += fmt::format("{:.6f}\t{:.6f}\t{}\n", phone.start_s, phone.end_s,
                           phone_label(phone, inventory.is_vowel(phone.symbol)));
    return out;
}

void write_phones_tsv(const std::filesystem::path& path, const PhoneSequence& phones) {
    write_text_file(path, phones_tsv(phones));
}

void write_phones_textgrid(const std::filesystem::path& path, const PhoneSequence& phones) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    TextGrid grid;
    grid.start_s = phones.empty() ? 0.0 : std::min(0.0, phones.front().start_s);
    grid.end_s = phones.empty() ? 0.0 : phones.back().end_s;
    Tier tier;
    tier.name = "phones";
    tier.start_s = grid.start_s;
    tier.end_s = grid.end_s;
    for (const Phone& phone : phones)
        tier.items.push_back({phone.start_s, phone.end_s, phone_label(phone, inventory.is_vowel(phone.symbol))});
    grid.tiers.push_back(std::move(tier));
    write_textgrid(path, grid);
}

void check_phone_sequence(const PhoneSequence& phones, const std::string& source_path, double tolerance_s) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    DiagnosticList problems;
    for (std::size_t k = 0; k < phones.size(); ++k) {
        const Phone& phone = phones[k];
        const std::string field = fmt::format("phone {} ({})", k + 1, phone.symbol);
        if (!inventory.contains(phone.symbol))
            problems.add(source_path, 0, 0, field, "expected a phone of the project set");
        if (!(phone.end_s > phone.start_s))
            problems.add(source_path, 0, 0, field,
                         fmt::format("expected end > start, got {} .. {}", phone.start_s, phone.end_s));
        if (k > 0 && std::abs(phone.start_s - phones[k - 1].end_s) > tolerance_s)
            problems.add(source_path, 0, 0, field,
                         fmt::format("expected a start at the previous phone's end ({}), got {}",
                                     phones[k - 1].end_s, phone.start_s));
    }
    problems.throw_if_any();
}

}  // namespace avsi
