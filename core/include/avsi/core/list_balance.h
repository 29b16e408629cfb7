// Seeded balanced assignment of a sentence corpus's test lists: lists whose
// means of the sentence measures (sentence_profile.h: keyword frequency,
// syllables, keyword viseme shares) are as equal as a seeded search finds,
// and the Markdown report of the balance. The lists follow the study's design
// (Beskow, "Trainable articulatory control models", §6.1: six sub-lists of 15
// everyday sentences after MacLeod & Summerfield 1990, three keywords each).
//
//   avsi::Corpus corpus = avsi::read_corpus("protocols/corpus/sentences.csv");
//   avsi::BalanceOutcome b = avsi::balance_corpus(corpus, {});
//   avsi::write_corpus("sentences.csv", b.corpus);   // b.report: Markdown
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/sentence_profile.h"
#include "avsi/core/word_table.h"

namespace avsi {

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

}  // namespace avsi
