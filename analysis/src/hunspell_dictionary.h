// A hunspell dictionary (libhunspell) as keyword scoring uses it for Swedish
// and German (language.h): is a normalised word a word of the language
// (inflected forms and compounds included, through the dictionary's affix
// and compound rules), and what are its stems (bilarna -> bil, Häuser ->
// Haus). Words arrive normalised (lower case, UTF-8); German nouns are
// capitalised in the dictionary, so a word is also tried with a capital
// first letter. The dictionary's own encoding (its SET line: UTF-8 or
// ISO8859-1) is converted to and from. libhunspell is not thread-safe, so
// each call holds the dictionary's lock.
#pragma once

#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

class Hunspell;

namespace avsi::analysis::detail {

class HunspellDictionary {
public:
    // /usr/share/hunspell/<name>.aff and .dic; throws InputError naming the
    // Debian package when they are missing, and for an encoding other than
    // UTF-8 or ISO8859-1.
    HunspellDictionary(const std::string& name, const std::string& package);
    ~HunspellDictionary();
    HunspellDictionary(const HunspellDictionary&) = delete;
    HunspellDictionary& operator=(const HunspellDictionary&) = delete;

    // The dictionary of that name, loaded on the first call in the process.
    static std::shared_ptr<const HunspellDictionary> shared(const std::string& name, const std::string& package);

    // Is the lower-case word (or its capitalised form) correctly spelled?
    bool spell(const std::string& word) const;
    // Its stems, lower case, without repeats (empty for a non-word).
    std::vector<std::string> stems(const std::string& word) const;

    const std::filesystem::path& dic_path() const { return m_dic; }
    double load_ms() const { return m_load_ms; }

private:
    std::string to_dictionary(const std::string& utf8) const;    // "" when not representable
    std::string from_dictionary(const std::string& text) const;  // to UTF-8

    std::unique_ptr<Hunspell> m_hunspell;
    mutable std::mutex m_mutex;
    bool m_latin1 = false;
    std::filesystem::path m_dic;
    double m_load_ms = 0.0;
};

// The word with its first letter upper-cased (ASCII, ä ö ü å é).
std::string capitalised(const std::string& lower_utf8);
// The word lower-cased (ASCII and the Latin-1 letters).
std::string lower_cased(const std::string& utf8);

}  // namespace avsi::analysis::detail
