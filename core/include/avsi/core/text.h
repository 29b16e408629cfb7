// Small text helpers every reader of user files needs: trimming and ASCII
// case folding, XML/HTML escaping. One definition for the project (they were repeated per file).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace avsi {

// `s` without leading and trailing ASCII white space (a view into `s`).
std::string_view trim_view(std::string_view s);

// `s` without leading and trailing ASCII white space, as a string.
std::string trim(std::string_view s);

// `s` with ASCII letters in lower case; other bytes (UTF-8 included) unchanged.
std::string ascii_lower(std::string_view s);

// The words of a text as written: runs of letters, digits, apostrophes and
// non-ASCII bytes (UTF-8 letters), without leading or trailing apostrophes; a
// possessive "'s" stays part of the word ("The dog's bowl." → The, dog's, bowl).
std::vector<std::string> text_words(std::string_view text);

// `s` with & < > " replaced by their XML entities (for SVG and HTML text and attributes).
std::string xml_escape(std::string_view s);

}  // namespace avsi
