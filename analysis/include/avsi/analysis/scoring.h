// Keyword scoring of typed responses (`avsi score`).
//
// Each response and each keyword is normalised (text_normalize.h), then the
// keywords of the sentence are matched against the response words by rules
// tried in this fixed order, best first:
//   1. exact      the keyword itself;
//   2. alternate  one of the keyword's accepted alternates from the corpus;
//   3. homophone  a homophone of the keyword or of an alternate
//                 (protocols/homophones.csv);
//   4. stem       same Snowball English stem (libstemmer) as the keyword or an
//                 alternate ("barking" for "barked");
//   5. typo       Damerau-Levenshtein (optimal string alignment) distance ≤ 1
//                 to the keyword or an alternate, both words of 5+ letters and
//                 not numbers; off in strict mode.
// Assignment: rule by rule (all keywords try rule 1, then the still unmatched
// keywords try rule 2, …); within a rule, keywords in sentence order, each
// taking the first unused response word(s) that match. A response word
// matches at most one keyword. Multi-word keywords ("ice cream") match
// consecutive unused words, each under the rule.
// Manual overrides (a CSV with a reason) are applied after the rules and kept
// in the override_reason column and an overrides log.
//
// Responses CSV (until the experiment module's export is used directly):
//   subject,session,trial,phase,condition,list,sentence,response
// phase is warmup, practice or test; only test trials are scored.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/scores.h"
#include "avsi/core/corpus.h"

namespace avsi::analysis {

enum class MatchRule { Exact, Alternate, Homophone, Stem, Typo, None };

// "exact", "alternate", "homophone", "stem", "typo", "none".
const char* rule_name(MatchRule rule);

// Groups of words that sound alike, after normalisation.
class HomophoneTable {
public:
    // Reads `words` rows ("to|too|two"); '#' lines are comments. Words that
    // normalise to more than one word are an error naming the line.
    static HomophoneTable read(const std::filesystem::path& path);
    void add_group(const std::vector<std::string>& normalized_words);
    bool are_homophones(const std::string& a, const std::string& b) const;
    std::size_t group_count() const { return m_group_count; }

private:
    std::map<std::string, std::vector<std::size_t>> m_groups_of;
    std::size_t m_group_count = 0;
};

struct ScoringSettings {
    bool strict = false;           // true: no typo tolerance
    std::size_t typo_min_letters = 5;
    std::filesystem::path homophones;  // empty: the shipped protocols/homophones.csv
};

// The outcome for one keyword of one response.
struct KeywordMatch {
    std::size_t keyword_index = 0;  // 1-based
    std::string keyword;
    std::string matched_word;       // normalised response word(s), "" if none
    MatchRule rule = MatchRule::None;
    bool correct = false;
};

// Scores responses against keywords. Holds a Snowball stemmer, so one
// instance per thread.
class KeywordScorer {
public:
    KeywordScorer(ScoringSettings settings, HomophoneTable homophones);
    explicit KeywordScorer(ScoringSettings settings = {});
    ~KeywordScorer();
    KeywordScorer(KeywordScorer&&) noexcept;
    KeywordScorer& operator=(KeywordScorer&&) noexcept;

    // One KeywordMatch per keyword of `sentence`, in keyword order.
    std::vector<KeywordMatch> score(const Sentence& sentence, std::string_view response);

    // The Snowball English stem of a normalised word.
    std::string stem(const std::string& word);

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

// One row of the responses CSV.
struct Response {
    std::string subject, session, trial, phase, condition, list, sentence, response;
    int line = 0;
};

// Reads the responses CSV; phase must be warmup, practice or test.
std::vector<Response> read_responses(const std::filesystem::path& path);

// One manual override: keyword `keyword_index` (1-based) of the trial (or,
// when trial is empty, the sentence) of a subject is set to `correct`.
struct Override {
    std::string subject, trial, sentence;
    std::size_t keyword_index = 0;
    bool correct = false;
    std::string reason;
    int line = 0;
};

// Reads subject,(trial|sentence),keyword_index,correct,reason; reason required.
std::vector<Override> read_overrides(const std::filesystem::path& path);

// One row of keywords.csv.
struct KeywordRow {
    std::string subject, session, trial, condition, list, sentence;
    KeywordMatch match;
    std::string response;
    std::string override_reason;  // "" unless a manual override applied
};

// One applied override, for the audit log.
struct OverrideLogEntry {
    Override item;
    std::string keyword, response;
    MatchRule rule = MatchRule::None;
    bool automatic_correct = false;
};

struct ScoringResult {
    std::vector<KeywordRow> keywords;
    Scores scores;  // subject × condition
    std::vector<OverrideLogEntry> overrides;
    std::size_t trials_scored = 0;
};

// Scores the test-phase responses and applies the overrides. Throws
// InputError for sentences missing from the corpus and for overrides that
// match no keyword.
ScoringResult score_responses(const Corpus& corpus, const std::vector<Response>& responses,
                              const std::vector<Override>& overrides, const ScoringSettings& settings = {});

// Subject × condition percent correct from keyword rows (first-appearance order).
Scores aggregate_scores(const std::vector<KeywordRow>& rows);

// keywords.csv: subject,condition,sentence,keyword_index,keyword,matched_word,
// rule,correct,override_reason,session,trial,list,response.
void write_keywords_csv(const std::filesystem::path& path, const std::vector<KeywordRow>& rows);
// overrides.csv audit log: every applied override with the automatic result.
void write_overrides_log(const std::filesystem::path& path, const std::vector<OverrideLogEntry>& log);

// `avsi score`: reads the inputs, scores, writes keywords.csv, scores.csv and
// (when overrides were given) overrides_applied.csv into out_dir.
struct ScoreFilesSettings {
    std::filesystem::path corpus, responses, out_dir, overrides;
    ScoringSettings scoring;
};
ScoringResult score_files(const ScoreFilesSettings& settings);

}  // namespace avsi::analysis
