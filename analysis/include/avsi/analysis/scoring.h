// Keyword scoring of typed responses (`avsi score`), the way a careful human
// scorer would mark them: no credit for a different word, whatever its
// spelling distance. docs/scoring.md gives the conventions and their sources.
//
// Each response and each keyword is normalised (text_normalize.h), then the
// keywords of the sentence are matched against the response words by rules
// tried in this fixed order, best first:
//   1. exact       the keyword itself;
//   2. number      the same number written the other way ("7" for "seven");
//   3. alternate   one of the keyword's accepted alternates from the corpus;
//   4. variant     a British/American spelling variant of the keyword or an
//                  alternate (protocols/spelling_variants.csv: colour/color);
//   5. homophone   a homophone of the keyword or an alternate
//                  (protocols/homophones.csv, General American; an RP table in
//                  homophones-rp.csv; per language, language.h);
//   5b. compound   a compound keyword typed as two or three consecutive words
//                  ("bil nyckel" for "bilnyckel"), under the rule sets from
//                  the protocol's [scoring] split_compounds on (never by
//                  default; the same spoken word, written apart);
//   6. inflection  a regular or listed inflection of the same lemma
//                  (inflection.h: boys/boy, helped/helps, rang/ring); for
//                  Swedish and German a shared hunspell stem (bilen, bilar,
//                  bilarna for bil; Häuser for Haus);
//   7. typo        a non-word (not in the lexicon, lexicon.h, nor in the corpus
//                  vocabulary; for Swedish and German not in the hunspell
//                  dictionary either) within one edit (Damerau-Levenshtein, optimal
//                  string alignment) of the keyword or an alternate, both of 5+
//                  letters: "gardne" for "garden", never "pound" for "found".
// A rule set names the rules that give credit (RuleSet):
//   strict   1-5: the keyword as spoken, whatever its spelling;
//   loose    1-6: also other inflections of the keyword's root, as in loose
//            keyword scoring;
//   lenient  1-7: also non-word misspellings.
// Assignment: rule by rule (all keywords try rule 1, then the still unmatched
// keywords try rule 2, …); within a rule, keywords in sentence order, each
// taking the first unused response word(s) that match. A response word
// matches at most one keyword. Multi-word keywords ("ice cream") match
// consecutive unused words, each under the rule (or equal).
// Manual overrides (a CSV, reason required when it changes a verdict) are
// applied after the rules and kept in the override_reason column and an
// overrides log; audit.csv lists every non-exact credit in the overrides
// layout; a second scorer's judgments in the same layout give percent
// agreement and Cohen's kappa per rule set (agreement.csv).
//
// One scorer object scores one response at a time, for batch files and for a
// live adaptive track alike:
//
//   avsi::analysis::ScoringSettings s = avsi::analysis::scoring_settings(protocol);
//   s.vocabulary = avsi::analysis::corpus_vocabulary(corpus);
//   const avsi::analysis::KeywordScorer scorer(s);  // once; then per answer:
//   auto matches = scorer.score(sentence, "the boys fell from the windows");
//
// Responses CSV (the experiment module's export):
//   subject,session,trial,phase,condition,list,sentence,response
// phase is warmup, practice or test; only test trials are scored.
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/analysis/scores.h"
#include "avsi/core/corpus.h"
#include "avsi/core/protocol.h"

namespace avsi::analysis {

enum class MatchRule { Exact, Number, Alternate, Variant, Homophone, Compound, Inflection, Typo, None };

// "exact", "number", "alternate", "variant", "homophone", "compound",
// "inflection", "typo", "none".
const char* rule_name(MatchRule rule);

// Named rule sets, each a superset of the one before.
enum class RuleSet { Strict, Loose, Lenient };
inline constexpr std::array<RuleSet, 3> kRuleSets = {RuleSet::Strict, RuleSet::Loose, RuleSet::Lenient};

// "strict", "loose", "lenient".
const char* rule_set_name(RuleSet set);
// The rule set of that name, or nullopt.
std::optional<RuleSet> parse_rule_set(std::string_view name);
// The names, in order (for choices and "did you mean").
std::vector<std::string> rule_set_names();
// Does `set` give credit by `rule`? (Compound: as ScoringSettings::split_compounds says.)
bool rule_set_allows(RuleSet set, MatchRule rule);

// Groups of words that count as the same word (homophones, spelling
// variants), after normalisation.
class WordGroups {
public:
    // Reads a table with a `words` column of groups ("to|too|two"); other
    // columns are documentation; '#' lines are comments. An entry that
    // normalises to more than one word is an error naming the line. Words are
    // normalised as words of `language` (language.h).
    static WordGroups read(const std::filesystem::path& path, std::string_view language = "en");
    void add_group(const std::vector<std::string>& normalized_words);
    // Are a and b (different words) in one group?
    bool same_group(const std::string& a, const std::string& b) const;
    // The other words of the groups of `word`.
    std::vector<std::string> partners(const std::string& word) const;
    std::size_t group_count() const { return m_group_count; }

private:
    std::map<std::string, std::vector<std::size_t>, std::less<>> m_groups_of;
    std::vector<std::vector<std::string>> m_groups;
    std::size_t m_group_count = 0;
};
using HomophoneTable = WordGroups;

struct ScoringSettings {
    RuleSet rules = RuleSet::Strict;
    // The language of the responses and keywords (language.h): its
    // normalisation, number words, homophones, spellings, inflections and lexicon.
    std::string language = "en";
    // The first rule set that credits a compound keyword typed apart
    // ("bil nyckel" for "bilnyckel"); nullopt: none does.
    std::optional<RuleSet> split_compounds;
    std::size_t typo_min_letters = 5;
    std::filesystem::path homophones;         // empty: the language's (English: protocols/homophones.csv, GA)
    std::filesystem::path spelling_variants;  // empty: the language's (English: protocols/spelling_variants.csv)
    std::filesystem::path inflections;        // empty: protocols/inflections.csv
    std::filesystem::path parts_of_speech;    // empty: protocols/lemma_pos.tsv
    std::vector<std::filesystem::path> lexicon;  // empty: the language's word lists (English: Lexicon::default_files())
    // Words that count as words besides the lexicon, so they are never typos:
    // the corpus vocabulary (corpus_vocabulary()).
    std::vector<std::string> vocabulary;
};

// The scoring settings a protocol asks for: its [scoring] rule set, homophone
// table and split_compounds, and the language of its voice (espeak:sv -> sv;
// Festival voices are English). Throws InputError at the protocol's tts line
// for a language keyword scoring has no tables for.
ScoringSettings scoring_settings(const Protocol& protocol);

// The protocol's language: [corpus] language, by default its voice's ("en"
// for Festival and the default voice); session.language is the same.
std::string protocol_language(const Protocol& protocol);

// The normalised words of every sentence, keyword and alternate of a corpus.
std::vector<std::string> corpus_vocabulary(const Corpus& corpus, std::string_view language = "en");

// The outcome for one keyword of one response.
struct KeywordMatch {
    std::size_t keyword_index = 0;  // 1-based
    std::string keyword;
    std::string matched_word;       // normalised response word(s), "" if none
    MatchRule rule = MatchRule::None;
    bool correct = false;
};

// Scores responses against keywords under one rule set. Loads only the tables
// its rule set uses (the lexicon only for lenient, shared by every scorer of
// the process). score() is const and may be called from several threads.
class KeywordScorer {
public:
    explicit KeywordScorer(ScoringSettings settings = {});
    ~KeywordScorer();
    KeywordScorer(KeywordScorer&&) noexcept;
    KeywordScorer& operator=(KeywordScorer&&) noexcept;

    // One KeywordMatch per keyword of `sentence`, in keyword order.
    std::vector<KeywordMatch> score(const Sentence& sentence, std::string_view response) const;

    const ScoringSettings& settings() const;
    // Is the normalised word a word (lexicon or vocabulary)? Lenient only;
    // other rule sets load no lexicon and answer false.
    bool is_word(const std::string& normalized_word) const;
    // Words in the lexicon and the time it took to load (0 when not loaded).
    std::size_t lexicon_size() const;
    double lexicon_load_ms() const;

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

// One judgment of one keyword: keyword `keyword_index` (1-based) of the trial
// (or, when trial is empty, the sentence) of a subject is `correct`. As a
// manual override it carries a reason; as a second scorer's mark it need not.
struct Override {
    std::string subject, trial, sentence;
    std::size_t keyword_index = 0;
    bool correct = false;
    std::string reason;
    int line = 0;
};

// Reads subject,(trial|sentence),keyword_index,correct[,reason] and ignores
// other columns, so keywords.csv and audit.csv are valid inputs. The reason
// may be empty in the file; an override whose verdict differs from the
// automatic one needs a reason (checked when applied).
std::vector<Override> read_overrides(const std::filesystem::path& path);

// One row of keywords.csv.
struct KeywordRow {
    std::string subject, session, trial, condition, list, sentence;
    KeywordMatch match;  // under the chosen rule set (correct after overrides)
    std::string response;
    std::string override_reason;  // "" unless a manual override changed or confirmed it
    // The automatic result of each rule set (index: RuleSet), for the audit
    // and the agreement.
    std::array<KeywordMatch, 3> by_set;
};

// One applied override, for the audit log.
struct OverrideLogEntry {
    Override item;
    std::string keyword, response;
    MatchRule rule = MatchRule::None;
    bool automatic_correct = false;
};

// Agreement between the automatic scoring and a second scorer.
struct AgreementRow {
    std::string scoring;       // a rule set name, or "<set>+overrides"
    std::size_t keywords = 0;  // keywords both judged
    std::size_t agreements = 0;
    std::size_t automatic_correct = 0, scorer_correct = 0;
    double percent_agreement = 0.0;
    std::optional<double> kappa;  // Cohen's kappa; nullopt (NA) when either side gives one verdict throughout
};
struct Disagreement {
    std::string scoring;
    std::size_t row = 0;  // index into ScoringResult::keywords
    bool automatic = false, scorer = false;
};
struct AgreementResult {
    std::vector<AgreementRow> rows;
    std::vector<Disagreement> disagreements;
    std::size_t keywords_scored = 0;  // keywords in the scoring, judged or not
};

// Cohen's kappa of two binary ratings from their 2x2 counts (both correct,
// a only, b only, neither); nullopt when expected agreement is 1.
std::optional<double> cohens_kappa(std::size_t both, std::size_t a_only, std::size_t b_only, std::size_t neither);

struct ScoringResult {
    RuleSet rules = RuleSet::Strict;
    std::vector<KeywordRow> keywords;
    Scores scores;  // subject × condition
    std::vector<OverrideLogEntry> overrides;
    std::size_t trials_scored = 0;
    std::size_t lexicon_words = 0;
    double lexicon_load_ms = 0.0;
};

// Scores the test-phase responses under every rule set, reports the chosen
// one (settings.rules) and applies the overrides to it. Throws InputError for
// sentences missing from the corpus and for overrides that match no keyword
// or change a verdict without a reason.
ScoringResult score_responses(const Corpus& corpus, const std::vector<Response>& responses,
                              const std::vector<Override>& overrides, const ScoringSettings& settings = {});

// Agreement of every rule set (and of the chosen set with the overrides, when
// any were applied) with a second scorer's judgments. Throws InputError for a
// judgment matching no scored keyword.
AgreementResult compare_with_scorer(const ScoringResult& result, const std::vector<Override>& judgments,
                                    const std::string& judgments_path);

// Subject × condition percent correct from keyword rows (first-appearance order).
Scores aggregate_scores(const std::vector<KeywordRow>& rows);

// keywords.csv: subject,condition,sentence,keyword_index,keyword,matched_word,
// rule,correct,override_reason,session,trial,list,response,rule_set.
void write_keywords_csv(const std::filesystem::path& path, const std::vector<KeywordRow>& rows, RuleSet rules);
// overrides.csv audit log: every applied override with the automatic result.
void write_overrides_log(const std::filesystem::path& path, const std::vector<OverrideLogEntry>& log);
// audit.csv: subject,trial,sentence,keyword_index,keyword,response_word,rule,
// rule_set,correct,reason,condition,response — every keyword the chosen set
// credits by a rule other than exact (correct 1), then every keyword only a
// more lenient set credits (correct 0, rule and rule_set of that set). The
// layout is the overrides layout: change `correct`, give a reason, and pass
// the file to --overrides.
void write_audit_csv(const std::filesystem::path& path, const ScoringResult& result);
// agreement.csv (scoring,keywords,agreements,percent_agreement,kappa,
// automatic_correct,scorer_correct) and disagreements.csv (scoring,subject,
// trial,sentence,keyword_index,keyword,response_word,rule,automatic,scorer,
// response) into `dir`.
void write_agreement(const std::filesystem::path& dir, const AgreementResult& agreement, const ScoringResult& result);

// `avsi score`: reads the inputs, scores, writes keywords.csv, scores.csv,
// audit.csv, (with overrides) overrides_applied.csv and (with a second
// scorer's file) agreement.csv and disagreements.csv into out_dir.
struct ScoreFilesSettings {
    std::filesystem::path corpus, responses, out_dir, overrides;
    std::filesystem::path agreement;  // a second scorer's judgments (optional)
    ScoringSettings scoring;
};
struct ScoreFilesResult {
    ScoringResult scoring;
    std::optional<AgreementResult> agreement;
};
ScoreFilesResult score_files(const ScoreFilesSettings& settings);

}  // namespace avsi::analysis
