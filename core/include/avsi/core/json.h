// JSON input with bounded nesting and compiler-style errors: every JSON file
// avsi reads (models, rigs, manifests, results) goes through parse_json, which
// refuses nesting deeper than a limit before nlohmann builds (and later
// recursively copies or prints) a DOM, and reports syntax errors as
// `file:line:col: error: …` instead of nlohmann's message text.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace avsi {

// Deeper than any file avsi writes (a model or manifest nests 4–6 levels),
// shallow enough that recursive copying and printing cannot exhaust the stack.
inline constexpr int max_json_depth = 64;

// Parses `text` (read from `path`, used in messages). Throws InputError with
// path:line:col for a syntax error, a number out of range or nesting deeper
// than `max_depth` (checked before the DOM is built).
nlohmann::json parse_json(std::string_view text, const std::string& path, int max_depth = max_json_depth);

// nlohmann's message without its "[json.exception.…]" prefix and position
// text, for a message of our own.
std::string json_error_text(const nlohmann::json::exception& error);

// The checks parse_json makes before parsing (nesting depth, numbers within
// a double's range), for readers that parse a stream of values themselves.
void check_json_structure(std::string_view text, const std::string& path, int max_depth = max_json_depth);

// Reads and parses a JSON file (as parse_json).
nlohmann::json read_json_file(const std::filesystem::path& path, int max_depth = max_json_depth);

// The string at `key` of `object`, or `fallback` when `object` is not an
// object, has no `key` or holds another type there. (nlohmann's
// value(key, "") throws a type_error for a key of another type.)
std::string json_string(const nlohmann::json& object, std::string_view key, std::string fallback = "");

// Call inside a catch block around code that reads fields of a parsed
// document: re-raises nlohmann's type and range errors (a string where a
// number belongs, a missing key) as InputError naming `path`, and anything
// else as rethrow_with_file does.
[[noreturn]] void rethrow_json_error(const std::filesystem::path& path);

// Runs `read()` (which reads fields of a document from `path`) and re-raises
// what escapes it through rethrow_json_error.
template <class Read>
auto with_json_context(const std::filesystem::path& path, Read&& read) -> decltype(read()) {
    try {
        return read();
    } catch (...) {
        rethrow_json_error(path);
    }
}

}  // namespace avsi
