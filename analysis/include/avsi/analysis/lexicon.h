// The lexicon of keyword scoring: which response words are words of the
// language, so that only non-words can be taken as misspellings of a keyword
// (rule "typo" of the lenient rule set, scoring.h). Below, English; Swedish
// and German read Debian's wswedish (/usr/share/dict/swedish) and wngerman
// (/usr/share/dict/ngerman) the same way, beside their hunspell dictionaries
// (language.h), which add the inflected forms and compounds the lists lack.
//
// The default lists are SCOWL's American and British lists as Debian ships
// them (packages wamerican and wbritish: /usr/share/dict/american-english and
// british-english, about 104,000 entries each with plurals, verb forms and
// possessives). A word is in the lexicon when it is in either list, so a
// British spelling typed by an American listener (or the reverse) is a word.
// Why these lists: each inflected form is a plain line (hunspell-en-us needs
// its affix rules expanded; WordNet holds base forms only, so "pounds" would
// not be a word), both varieties come from one source, and the size-50 lists
// hold the words of ordinary dictionaries without the rare words that would
// turn common misspellings into "words" (the larger SCOWL sizes list more).
// Entries are normalised like responses (text_normalize.h); capitalised
// entries (names: Mable, Paris) and possessives ('s) are left out, the first
// because a lower-case response word is not a name, the second because
// normalisation removes the possessive from responses.
//
// Reading ~200,000 lines takes tens of milliseconds, so each file set is read
// once per process and shared (Lexicon::shared); lookups are a binary search
// over one sorted array.
#pragma once

#include <filesystem>
#include <memory>
#include <utility>
#include <string>
#include <string_view>
#include <vector>

namespace avsi::analysis {

class Lexicon {
public:
    // The Debian word lists (/usr/share/dict/american-english, british-english).
    static std::vector<std::filesystem::path> default_files();

    // Reads the files (one word per line, UTF-8), normalised as words of
    // `language` (language.h). Throws InputError for a missing or unreadable
    // file, naming the Debian package that ships it. German keeps its
    // capitalised entries (nouns), lower-cased; other languages leave them
    // out (names).
    static Lexicon read(const std::vector<std::filesystem::path>& files, std::string_view language = "en");

    // The lexicon of `files` (empty: default_files()), read on the first call
    // in this process and shared afterwards. Thread-safe.
    static std::shared_ptr<const Lexicon> shared(const std::vector<std::filesystem::path>& files = {},
                                                 std::string_view language = "en");

    // Is the normalised word in the lexicon?
    bool contains(std::string_view normalized_word) const;

    std::size_t size() const { return m_words.size(); }
    const std::vector<std::filesystem::path>& files() const { return m_files; }
    double load_ms() const { return m_load_ms; }  // time read() took

private:
    std::vector<char> m_arena;             // the words, '\0'-separated
    std::vector<std::string_view> m_words; // sorted, unique views into m_arena
    std::vector<std::filesystem::path> m_files;
    double m_load_ms = 0.0;
};

}  // namespace avsi::analysis
