// JSON input with bounded nesting and file:line:col errors (see json.h).
#include "avsi/core/json.h"

#include <cmath>
#include <cstdlib>
#include <string>

#include <fmt/format.h>

#include "avsi/core/checks.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi {

namespace {

struct Position {
    int line = 1;
    int column = 1;
};

// Line and column (1-based, in bytes) of byte `offset` of `text`.
Position position_of(std::string_view text, std::size_t offset) {
    Position p;
    offset = std::min(offset, text.size());
    for (std::size_t i = 0; i < offset; ++i) {
        if (text[i] == '\n') {
            ++p.line;
            p.column = 1;
        } else {
            ++p.column;
        }
    }
    return p;
}

// One pass over the text before nlohmann sees it: nesting depth, and numbers
// too large for a double (nlohmann reports those without a position).
// Strings are skipped (with their escapes); syntax is left to the parser.
void scan_structure(std::string_view text, const std::string& path, int max_depth) {
    int depth = 0;
    int line = 1;
    std::size_t line_start = 0;
    const std::size_t n = text.size();
    for (std::size_t i = 0; i < n; ++i) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
            line_start = i + 1;
        } else if (c == '"') {
            for (++i; i < n && text[i] != '"'; ++i) {
                if (text[i] == '\\') ++i;
                else if (text[i] == '\n') return;  // invalid JSON: the parser reports it
            }
        } else if (c == '[' || c == '{') {
            if (++depth > max_depth)
                throw InputError(path, line, static_cast<int>(i - line_start) + 1, "nesting",
                                 fmt::format("expected JSON nested at most {} levels deep, got deeper", max_depth));
        } else if (c == ']' || c == '}') {
            --depth;
        } else if (c == '-' || (c >= '0' && c <= '9')) {
            std::size_t j = i;
            while (j < n && (std::isdigit(static_cast<unsigned char>(text[j])) || text[j] == '-' || text[j] == '+' ||
                             text[j] == '.' || text[j] == 'e' || text[j] == 'E'))
                ++j;
            const std::string number(text.substr(i, j - i));
            const double value = std::strtod(number.c_str(), nullptr);
            if (!std::isfinite(value))
                throw InputError(path, line, static_cast<int>(i - line_start) + 1, "number",
                                 fmt::format("expected a number within the range of a double, got {}",
                                             number.size() > 40 ? number.substr(0, 40) + "…" : number));
            i = j - 1;
        }
    }
}

// nlohmann's message without "[json.exception.…] " and "parse error at line
// L, column C: " (the position goes in front, compiler style).
std::string plain_message(const std::string& what) {
    std::string out = what;
    if (out.rfind("[json.exception.", 0) == 0) {
        const auto close = out.find("] ");
        if (close != std::string::npos) out = out.substr(close + 2);
    }
    if (out.rfind("parse error", 0) == 0) {
        const auto column = out.find("column ");
        const auto colon = out.find(": ", column == std::string::npos ? 0 : column);
        if (colon != std::string::npos) out = out.substr(colon + 2);
    }
    return out;
}

}  // namespace

namespace {

// nlohmann's lexer takes a NUL byte for the end of the input: a document
// followed by a NUL and anything at all would pass. JSON text has no raw NUL
// (not even in strings, where control characters are escaped).
void refuse_nul(std::string_view text, const std::string& path) {
    if (const auto z = text.find('\0'); z != std::string_view::npos) {
        const Position p = position_of(text, z);
        throw InputError(path, p.line, p.column, "", "invalid JSON: a NUL byte (binary data in a JSON file?)");
    }
}

}  // namespace

nlohmann::json parse_json(std::string_view text, const std::string& path, int max_depth) {
    refuse_nul(text, path);
    scan_structure(text, path, max_depth);
    try {
        return nlohmann::json::parse(text.begin(), text.end());
    } catch (const nlohmann::json::parse_error& e) {
        const Position p = position_of(text, e.byte > 0 ? e.byte - 1 : 0);
        throw InputError(path, p.line, p.column, "", "invalid JSON: " + plain_message(e.what()));
    } catch (const nlohmann::json::exception& e) {
        throw InputError(std::filesystem::path(path), "invalid JSON: " + plain_message(e.what()));
    } catch (...) {
        rethrow_with_file(path, "parsing");
    }
}

void check_json_structure(std::string_view text, const std::string& path, int max_depth) {
    refuse_nul(text, path);
    scan_structure(text, path, max_depth);
}

std::string json_error_text(const nlohmann::json::exception& error) { return plain_message(error.what()); }

nlohmann::json read_json_file(const std::filesystem::path& path, int max_depth) {
    return parse_json(read_text_file(path), path.string(), max_depth);
}

std::string json_string(const nlohmann::json& object, std::string_view key, std::string fallback) {
    if (!object.is_object()) return fallback;
    const auto it = object.find(key);
    return it != object.end() && it->is_string() ? it->get<std::string>() : fallback;
}

void rethrow_json_error(const std::filesystem::path& path) {
    try {
        throw;
    } catch (const nlohmann::json::exception& e) {
        throw InputError(path, "unexpected JSON content: " + plain_message(e.what()));
    } catch (...) {
        rethrow_with_file(path);
    }
}

}  // namespace avsi
