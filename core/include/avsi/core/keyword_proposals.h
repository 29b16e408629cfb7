// Keyword proposals for a sentence list as people write it (`avsi corpus
// import`): the list read with its numbering, bullets and "List N" headings
// taken off, then per sentence the content words ranked (word_table.h: parts
// of speech, function words, Zipf frequency) and the best chosen as keywords,
// with alternates a person reviews.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/word_table.h"

namespace avsi {

// An alternate form of a keyword a scorer may want to accept, and why.
struct AlternateProposal {
    std::string word;
    std::string reason;  // "plural", "spelling variant", …
};
// Proposes alternates for a (lower-case) keyword. The scoring module's
// inflection and spelling-variant tables provide one (analysis/alternates.h);
// core cannot depend on analysis, so the caller passes it in.
using AlternateProposer = std::function<std::vector<AlternateProposal>(const std::string& keyword)>;

struct ImportSettings {
    int keywords = 3;            // keywords proposed per sentence
    int min_syllables = 7;       // syllable range reported (0 and 0: not counted)
    int max_syllables = 9;
    std::string voice = "en-us";
    std::string id_prefix = "s"; // ids s001, s002, …
    AlternateProposer alternates;  // empty: no alternates proposed
};

// One sentence of a list as people write them, with what was taken off it.
struct ListedSentence {
    std::string text;        // without its numbering
    std::string list;        // from the last "List N" heading before it ("" if none)
    int line = 0;            // line in the file
    std::string numbering;   // the numbering removed ("1.", "(12)", "-"), or ""
};

// What import_sentences did with one line.
struct ImportedSentence {
    Sentence sentence;                 // keywords chosen (may be fewer than asked)
    int syllables = 0;                 // 0 when not counted
    std::vector<std::string> notes;    // per word: why chosen or not
    bool complete = false;             // got the number of keywords asked for
};

struct ImportOutcome {
    Corpus corpus;                        // sentences with at least one keyword
    std::vector<ImportedSentence> sentences;  // every input sentence
    std::string report;                   // plain text, one block per sentence, then a summary
};

// Proposes keywords for sentences (one per string): content words, i.e. not in
// the function-word list; nouns, verbs and adjectives (WordNet) before
// adverbs and words WordNet does not list; within a rank the least frequent
// (lowest Zipf value, WordTable::zipf; unknown forms count as rarest) first,
// as the most informative, then in sentence order; a word is used once. The
// chosen keywords are written in sentence order. With settings.alternates,
// each keyword's proposed alternates are listed in the report and in the
// sentence's `review` column (keyword|alternate syntax), not in its keywords:
// a person decides which to accept.
ImportOutcome import_sentences(const std::vector<std::string>& texts, const ImportSettings& settings,
                               const WordTable& words = WordTable::builtin());
// The same for sentences read by read_sentence_lines: their list headings set
// the `list` column and the report says what numbering was removed.
ImportOutcome import_listed_sentences(const std::vector<ListedSentence>& sentences, const ImportSettings& settings,
                                      const WordTable& words = WordTable::builtin());
// Reads a sentence list as people write it: one sentence a line; blank lines
// and '#' comments skipped; numbering ("1.", "1)", "(1)", "[1]", "1:", a
// number and a tab) and bullets ("-", "*", "•") removed; a heading "List N"
// (also "## List 1", "Harvard list 2:", "LIST 3") starts list N; Markdown
// rules ("---") are skipped. Throws InputError if it cannot be read or holds
// no sentence, and with file:line for a numbering with no sentence after it
// ("4." alone) and for an item number that repeats or falls within a list
// (a pasted or misplaced line; a list may start again at 1).
std::vector<ListedSentence> read_sentence_lines(const std::filesystem::path& path);
// The texts of read_sentence_lines.
std::vector<std::string> read_sentence_list(const std::filesystem::path& path);

}  // namespace avsi
