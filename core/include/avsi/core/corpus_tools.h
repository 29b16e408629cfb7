// Tools for sentence corpora (corpus.h): the measures a test list is balanced
// on, a seeded balanced assignment of test lists, and keyword proposals for an
// unmarked sentence list.
//
// Measures (per sentence):
//   syllables        vowel phones of the espeak-ng rendering of the text (tts.h);
//                    syllabic consonants count, since the phone map writes them AH0 + C.
//   keyword log frequency  log10(1 + n), n = SemCor sense-tagged count of the
//                    keyword's lemma (WordNet 3.0 cntlist.rev, derived into
//                    protocols/corpus/word-frequency.tsv by scripts/make-word-frequency).
//   keyword visemes  the keywords' phones (each keyword spoken alone) counted
//                    per visual class of VisemeClass, from the phone features
//                    of protocols/phones.tsv.
// The lists follow the study's design (Beskow, "Trainable articulatory control
// models", §6.1: six sub-lists of 15 everyday sentences after MacLeod &
// Summerfield 1990, three keywords each).
//
//   avsi::Corpus corpus = avsi::read_corpus("protocols/corpus/sentences.csv");
//   avsi::BalanceOutcome b = avsi::balance_corpus(corpus, {});
//   avsi::write_corpus("sentences.csv", b.corpus);   // b.report: Markdown
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/phones.h"

namespace avsi {

// One lemma a word form can come from, with its frequency.
struct WordFrequency {
    std::string lemma;
    long long count = 0;   // SemCor tag count of the lemma (all senses, all parts of speech)
    std::string pos;       // WordNet parts of speech: letters of "nvar"
};

// Word frequencies, parts of speech and function words.
class WordTable {
public:
    // protocols/corpus/word-frequency.tsv, protocols/corpus/function-words.txt
    // and protocols/corpus/word-zipf.tsv (loaded once).
    static const WordTable& builtin();
    // Reads a frequency table (word, lemma, count, pos; '#' comments), a
    // function-word list (one word a line) and optionally a Zipf table (word,
    // zipf). Throws InputError naming file:line.
    static WordTable load(const std::filesystem::path& frequency_tsv,
                          const std::filesystem::path& function_words,
                          const std::filesystem::path& zipf_tsv = {});

    // The lemmas `word` (any case) can be a form of, highest count first: the
    // table's own rows (lemma or irregular form), then WordNet's regular
    // suffix rules (morphy: dogs → dog, barked → bark, bigger → big) where the
    // lemma exists with that part of speech. Empty when unknown.
    std::vector<WordFrequency> lookup(std::string_view word) const;
    // log10(1 + count) of the most frequent lemma; 0 for an unknown word.
    double log_frequency(std::string_view word) const;
    bool is_function_word(std::string_view word) const;
    // The word form's frequency on the Zipf scale, log10(per billion words),
    // from the Zipf table (scripts/make-word-zipf: CMU Sphinx's US English
    // language model); nullopt when the table does not know the form.
    std::optional<double> zipf(std::string_view word) const;
    std::size_t size() const { return m_rows.size(); }

private:
    std::multimap<std::string, WordFrequency, std::less<>> m_rows;
    std::map<std::string, std::string, std::less<>> m_lemma_pos;  // lemma → parts of speech
    std::set<std::string, std::less<>> m_function_words;
    std::map<std::string, double, std::less<>> m_zipf;
};

// Visual classes of phones for balancing viseme content, by lip shape first:
// the first that applies wins.
enum class VisemeClass : int {
    Bilabial = 0,  // lips closed: P B M
    Labiodental,   // lower lip to teeth: F V
    Dental,        // tongue between teeth: TH DH
    Rounded,       // rounded or protruded lips (rounded or protruded ≥ 0.5): W R SH ZH CH JH, OW UW UH AO OY AW ER
    OpenVowel,     // open (jaw-lowered) vowels: AA AE AY
    SpreadVowel,   // other vowels: AH EH EY IH IY
    Lingual,       // consonants with neutral lips: T D N S Z L K G NG HH Y
    Count
};
inline constexpr std::size_t viseme_class_count = static_cast<std::size_t>(VisemeClass::Count);
// "bilabial", "labiodental", "dental", "rounded", "open vowel", "spread vowel", "lingual".
const char* to_string(VisemeClass c);
// The class of a speech phone from its features (not for `sil`).
VisemeClass viseme_class(const PhoneInfo& phone);

// The balance measures of one sentence.
struct SentenceProfile {
    std::string id;
    int syllables = 0;
    std::vector<double> keyword_log_frequency;  // one per keyword
    std::array<int, viseme_class_count> keyword_visemes{};  // keyword phones per class

    // Mean keyword log frequency (0 without keywords).
    double mean_log_frequency() const;
    int keyword_phones() const;
};

struct ProfileSettings {
    std::string voice = "en-us";   // espeak-ng voice for syllables and keyword phones
};

// Vowel phones in the espeak-ng rendering of `text`.
int count_syllables(const std::string& text, const std::string& voice = "en-us");
// Syllables, keyword frequencies and keyword visemes of a sentence.
SentenceProfile profile_sentence(const Sentence& sentence, const WordTable& words,
                                 const ProfileSettings& settings = {});

struct BalanceSettings {
    int lists = 6;                 // test lists
    int sentences_per_list = 15;
    std::uint64_t seed = 2004;     // seed of the search
    int restarts = 16;             // independent seeded starts; the best is kept
    int iterations = 40000;        // swap proposals per start (simulated annealing)
    int min_syllables = 7;         // range reported as a problem when a sentence is outside
    int max_syllables = 9;
    double frequency_weight = 2.0; // weight of the keyword-frequency term in the cost
    double syllable_weight = 1.0;  // weight of the syllable term
    double viseme_weight = 0.5;    // weight of each viseme-class share term
    ProfileSettings profile;
};

// The test lists chosen by balance_lists: indices into the profiles.
struct ListAssignment {
    std::vector<std::vector<std::size_t>> lists;  // sorted indices per list
    std::vector<std::size_t> unused;              // candidates left out
    double cost = 0.0;  // Σ weighted squared z-scores: list means against their mean, that mean against all candidates
};

// Chooses lists × sentences_per_list of `candidates` (indices into
// `profiles`) and splits them into lists whose means of the measures are as
// equal as the seeded search finds: simulated annealing over swaps (between
// lists, and between a list and the unused candidates), `restarts` times from
// seeded random assignments. When candidates are left out, the cost also keeps
// the test set's means near those of all candidates (so the search cannot buy
// balance by dropping every sentence with a rare feature). Deterministic for
// given inputs and settings.
// Throws InputError if there are too few candidates.
ListAssignment balance_lists(const std::vector<SentenceProfile>& profiles,
                             const std::vector<std::size_t>& candidates, const BalanceSettings& settings);
// The cost balance_lists minimises, for any assignment.
double balance_cost(const std::vector<SentenceProfile>& profiles,
                    const std::vector<std::vector<std::size_t>>& lists,
                    const std::vector<std::size_t>& candidates, const BalanceSettings& settings);

struct BalanceOutcome {
    Corpus corpus;                         // the input with the `list` column reassigned
    std::vector<SentenceProfile> profiles; // one per sentence, in corpus order
    ListAssignment assignment;
    std::string report;                    // Markdown (balance_report)
};

// Balances a corpus: sentences marked "warmup" or "practice" keep their mark;
// every other sentence (a list number or empty) is a candidate for the test
// lists, and candidates left out get an empty list. Throws InputError for
// other list values or too few candidates.
BalanceOutcome balance_corpus(const Corpus& corpus, const BalanceSettings& settings,
                              const WordTable& words = WordTable::builtin());

// The balance report: per list the mean and SD of keyword log frequency and
// syllables and the keyword viseme shares; across lists one-way ANOVA F tests,
// a χ² test of the viseme counts and the largest differences; the same for a
// seeded random assignment for comparison; sentences outside the syllable range.
std::string balance_report(const Corpus& corpus, const std::vector<SentenceProfile>& profiles,
                           const ListAssignment& assignment, const BalanceSettings& settings,
                           const std::string& command_line);

// One-way ANOVA of groups of values: F, its degrees of freedom and p.
struct OneWayAnova {
    double f = 0.0;
    int df_between = 0;
    int df_within = 0;
    double p = 1.0;
};
OneWayAnova one_way_anova(const std::vector<std::vector<double>>& groups);

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
