// The sentence corpus: one CSV row per sentence with its scoring keywords.
//
//   id,text,keywords[,list][,audio][,labels][,review]
//   s001,"The dog barked at the mailman.","dog|dogs;barked|barking;mailman|postman"
//
// `keywords`: keywords separated by ';', each with accepted alternates after
// '|' (the first is the keyword itself). `list` (optional): a test list number,
// or "practice" / "warmup". `audio` and `labels` (optional): a recording and
// its phone alignment (TextGrid/.lab/.tsv), relative to the corpus file.
// `review` (optional): alternates `avsi corpus import` proposes for a person
// to check, in the keywords syntax; scoring does not use them.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace avsi {

struct Keyword {
    std::string word;                     // as written in the corpus
    std::vector<std::string> alternates;  // accepted alternatives
};

struct Sentence {
    std::string id;
    std::string text;
    std::vector<Keyword> keywords;
    std::string list;                    // "" when not assigned
    std::filesystem::path audio;         // empty when TTS is used
    std::filesystem::path labels;        // empty when TTS is used
    std::string review;                  // proposed alternates to check ("" if none)
    int line = 0;                        // line in the corpus file
};

struct Corpus {
    std::filesystem::path path;
    std::vector<Sentence> sentences;

    // The sentence with that id; throws InputError if absent.
    const Sentence& sentence(const std::string& id) const;
};

// Reads and validates a corpus file: ids unique and non-empty, text
// non-empty, at least one keyword per sentence, each keyword in the text
// (case-insensitive). All problems are reported at once.
Corpus read_corpus(const std::filesystem::path& path);

// Writes a corpus in the same format (atomically).
void write_corpus(const std::filesystem::path& path, const Corpus& corpus);

}  // namespace avsi
