// What the subject reads, per language, from one table:
// protocols/languages/<lang>/strings.toml, with a [session] table (the
// defaults of a protocol's [session] texts: instructions, practice and test
// instructions, break and end texts), a [runner] table (the session
// runner's prompts, key hints, feedback, pause and progress line, which the
// online study shows too) and a [web] table (the online study's start,
// level, headphone-check and end screens and buttons). Every
// language's table has exactly the keys and the {placeholders} of the English
// one (read_ui_strings checks them), so a screen never falls back to English
// or shows a placeholder unfilled.
//
//   const avsi::UiStrings& s = avsi::ui_strings("sv");
//   s.text("runner", "answer_prompt");                 // "Vad hörde du? …"
//   s.fill("runner", "progress", {{"position", "3"}, {"total", "90"}});
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace avsi {

class UiStrings {
public:
    // The table of `language` under protocols/languages/; throws InputError
    // naming the file when there is none or it is malformed.
    static UiStrings read(const std::filesystem::path& file, const std::string& language);

    const std::string& language() const { return m_language; }
    // The text of `section`.`key` (a programmer error if absent: every table
    // has every key of the English one).
    const std::string& text(std::string_view section, std::string_view key) const;
    // The text with each {name} replaced by its value.
    std::string fill(std::string_view section, std::string_view key,
                     const std::vector<std::pair<std::string, std::string>>& values) const;
    // Every (key, text) of a section, by key (for the web study's config).
    std::vector<std::pair<std::string, std::string>> section(std::string_view section) const;

private:
    std::string m_language;
    std::map<std::string, std::string, std::less<>> m_texts;  // "section.key" -> text
};

// protocols/languages/<language>/strings.toml
std::filesystem::path ui_strings_file(const std::string& language);

// The table of a language, read on the first call and checked against the
// English table's keys and placeholders. Throws InputError for a language
// without a table. Thread-safe.
const UiStrings& ui_strings(const std::string& language);


}  // namespace avsi
