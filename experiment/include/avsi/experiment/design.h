// The counterbalanced design of the perceptual test (seed 001 §6): per
// subject, unscored warm-up sentences, practice sentences, then one block per
// condition, each block one test list. List↔condition pairing is a Latin
// square over subjects (subject s pairs list l with condition (l + s − 1) mod k),
// so over k·m subjects every list meets every condition m times. Condition
// order is a seeded random permutation per subject, or a Williams design
// (Williams 1949: balanced for first-order carry-over; 2k rows for odd k).
// Sentence order within a block is shuffled per subject (seeded). With an
// [adaptive] section whose tracks are interleaved, the blocks' sentences then
// alternate one by one in block order (all in test block 1).
//
// lists.csv: subject,position,phase,block,list,condition,sentence,stimulus
// (stimulus = "<sentence>/<condition>.mp4", the stimulus folder layout).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/protocol.h"

namespace avsi::experiment {

enum class Phase { Warmup, Practice, Test };
std::string to_string(Phase phase);
// Parses "warmup" / "practice" / "test"; false when the text is none of them.
bool parse_phase(const std::string& text, Phase& phase);

struct PlannedTrial {
    int subject = 0;
    int position = 0;   // 1-based within the subject's session
    Phase phase = Phase::Test;
    int block = 0;      // 0 for warm-up and practice; test blocks 1..k
    std::string list;   // "1".."L", "warmup", "practice"
    std::string condition;
    std::string sentence;
    std::string stimulus;  // relative to the stimulus folder

    bool operator==(const PlannedTrial&) const = default;
};

// Which sentences make up the warm-up, practice and each test list.
struct ListAssignment {
    std::vector<std::string> warmup;
    std::vector<std::string> practice;
    std::vector<std::vector<std::string>> lists;  // lists[l] = sentence ids of list l+1
};

// Lists from the corpus' `list` column when present (counts must match the
// design exactly), otherwise a seeded assignment of equal-size lists.
// Throws InputError naming the corpus file when the corpus cannot fill the design.
ListAssignment assign_lists(const Corpus& corpus, const DesignSettings& design);

// Rows of a Williams design for k treatments: k rows for even k, 2k for odd k.
// Each row is an order of 0..k-1; each treatment appears equally often at each
// position, and each ordered pair of neighbours equally often.
std::vector<std::vector<int>> williams_design(int k);

// The order of the k conditions (indices) for one subject (1-based).
std::vector<int> condition_order(const DesignSettings& design, int k, int subject);

// The condition index paired with list l (0-based) for a subject: (l + s − 1) mod k.
int paired_condition(int list_index, int subject, int k);

// Every planned trial of one subject.
std::vector<PlannedTrial> design_subject(const Protocol& protocol, const ListAssignment& lists,
                                         int subject);

// Subjects 1..n, concatenated.
std::vector<PlannedTrial> make_design(const Protocol& protocol, const Corpus& corpus, int subjects);

// Writes lists.csv atomically.
void write_lists_csv(const std::filesystem::path& path, const std::vector<PlannedTrial>& trials);
// Reads lists.csv (validating every field; problems reported with file:line).
std::vector<PlannedTrial> read_lists_csv(const std::filesystem::path& path);

// Counts of test trials per list × condition and per condition × block position.
struct BalanceReport {
    std::vector<std::string> conditions;
    std::vector<std::string> lists;
    std::vector<std::vector<int>> list_by_condition;      // [list][condition]
    std::vector<std::vector<int>> condition_by_position;  // [condition][block-1]
    int subjects = 0;
    // A readable table of both counts.
    std::string text() const;
};
BalanceReport balance_report(const Protocol& protocol, const std::vector<PlannedTrial>& trials);

}  // namespace avsi::experiment
