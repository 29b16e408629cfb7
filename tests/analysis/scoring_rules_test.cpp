// The keyword/response table of tests/data/analysis/scoring_rules.csv: every
// rule and every trap of issue 18 (real-word neighbours of long keywords,
// shared stems, non-homophones, true homophones, number words, spelling
// variants, inflections, non-word typos) with the verdict a careful human
// scorer gives under each rule set.
#include <array>
#include <map>
#include <set>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "avsi/analysis/inflection.h"
#include "avsi/analysis/lexicon.h"
#include "avsi/analysis/scoring.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/text.h"

namespace avsi::analysis {
namespace {

const KeywordScorer& scorer(RuleSet set) {
    static const std::array<KeywordScorer, 3> scorers = [] {
        auto make = [](RuleSet s) {
            ScoringSettings settings;
            settings.rules = s;
            return KeywordScorer(settings);
        };
        return std::array<KeywordScorer, 3>{make(RuleSet::Strict), make(RuleSet::Loose), make(RuleSet::Lenient)};
    }();
    return scorers[std::size_t(set)];
}

struct Row {
    std::string keyword, response, note;
    std::array<std::string, 3> expected;  // rule name per rule set
    int line = 0;
};

std::vector<Row> table() {
    const CsvTable t = read_csv(std::filesystem::path(AVSI_TEST_DATA_DIR) / "analysis" / "scoring_rules.csv");
    std::vector<Row> rows;
    for (const auto& r : t.rows) {
        Row row;
        row.keyword = r.fields[t.require_column("keyword")];
        row.response = r.fields[t.require_column("response")];
        row.expected = {trim(r.fields[t.require_column("strict")]), trim(r.fields[t.require_column("loose")]),
                        trim(r.fields[t.require_column("lenient")])};
        row.note = r.fields[t.require_column("what it checks")];
        row.line = r.line;
        rows.push_back(std::move(row));
    }
    return rows;
}

Sentence sentence_of(const std::string& keyword_field) {
    Sentence s;
    s.id = "s";
    Keyword k;
    std::vector<std::string> parts;
    std::string part;
    for (char c : keyword_field + "|") {
        if (c == '|') {
            parts.push_back(part);
            part.clear();
        } else {
            part += c;
        }
    }
    k.word = parts.front();
    k.alternates.assign(parts.begin() + 1, parts.end());
    s.keywords = {k};
    s.text = k.word;
    return s;
}

TEST(ScoringRules, TableCoversEveryRuleAndEveryTrapOfTheIssue) {
    const auto rows = table();
    EXPECT_GE(rows.size(), 60u);
    std::set<std::string> rules;
    std::set<std::pair<std::string, std::string>> pairs;
    for (const auto& r : rows) {
        for (const auto& e : r.expected) rules.insert(e);
        pairs.emplace(r.keyword, r.response);
    }
    for (const char* rule : {"exact", "number", "alternate", "variant", "homophone", "inflection", "typo", "none"})
        EXPECT_TRUE(rules.count(rule)) << "no row expects rule " << rule;
    // The pairs named in the issue (keyword, response as typed).
    const std::vector<std::pair<std::string, std::string>> traps = {
        {"found", "pound"},   {"mother", "bother"}, {"lunch", "punch"},      {"light", "night"},
        {"glass", "grass"},   {"horse", "house"},   {"dinner", "winner"},    {"evening", "even"},
        {"engine", "engineer"}, {"clothes", "cloth"}, {"been", "bean"},     {"what", "watt"},
        {"garden", "the gardne"}, {"breakfast", "brekfast"}, {"boys", "a boy"}, {"window", "the windows"},
        {"range", "rang"},    {"helped", "she helps"}};
    for (const auto& t : traps) EXPECT_TRUE(pairs.count(t)) << t.first << " / " << t.second << " missing";
}

TEST(ScoringRules, EveryPairGetsTheExpectedVerdictUnderEachRuleSet) {
    for (const auto& r : table()) {
        const Sentence s = sentence_of(r.keyword);
        for (RuleSet set : kRuleSets) {
            SCOPED_TRACE(fmt::format("scoring_rules.csv:{}: keyword \"{}\", response \"{}\" ({}), rule set {}", r.line,
                                     r.keyword, r.response, r.note, rule_set_name(set)));
            const auto m = scorer(set).score(s, r.response);
            ASSERT_EQ(m.size(), 1u);
            const std::string& expected = r.expected[std::size_t(set)];
            EXPECT_EQ(rule_name(m[0].rule), expected);
            EXPECT_EQ(m[0].correct, expected != "none");
        }
    }
}

TEST(ScoringRules, RuleSetsAreNested) {
    // Whatever strict credits, loose credits; whatever loose credits, lenient credits.
    for (const auto& r : table()) {
        const Sentence s = sentence_of(r.keyword);
        const bool strict = scorer(RuleSet::Strict).score(s, r.response)[0].correct;
        const bool loose = scorer(RuleSet::Loose).score(s, r.response)[0].correct;
        const bool lenient = scorer(RuleSet::Lenient).score(s, r.response)[0].correct;
        EXPECT_TRUE(!strict || loose) << r.keyword << " / " << r.response;
        EXPECT_TRUE(!loose || lenient) << r.keyword << " / " << r.response;
    }
}

TEST(Lexicon, EnglishWordsAreWordsAndMisspellingsAreNot) {
    const auto lexicon = Lexicon::shared();
    EXPECT_GT(lexicon->size(), 60000u);
    for (const char* w : {"pound", "bother", "punch", "night", "grass", "house", "winner", "colour", "color", "cafe"})
        EXPECT_TRUE(lexicon->contains(w)) << w;
    for (const char* w : {"gardne", "brekfast", "kitchne", "mable", "paris"}) EXPECT_FALSE(lexicon->contains(w)) << w;
    // Read once per process: the second call returns the same object.
    EXPECT_EQ(Lexicon::shared().get(), lexicon.get());
}

TEST(Lexicon, MissingWordListNamesItsFile) {
    try {
        (void)Lexicon::read({"/nonexistent/american-english"});
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/american-english"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("wamerican"), std::string::npos) << e.what();
    }
}

TEST(Lexicon, CorpusVocabularyIsNeverATypo) {
    // "kitchin" is not English, but a corpus that uses it as a word (a name,
    // say) makes it one: then it is no misspelling of "kitchen".
    ScoringSettings settings;
    settings.rules = RuleSet::Lenient;
    settings.vocabulary = {"kitchin"};
    const KeywordScorer with_word(settings);
    const Sentence s = sentence_of("kitchen");
    EXPECT_EQ(with_word.score(s, "kitchin")[0].rule, MatchRule::None);
    EXPECT_EQ(scorer(RuleSet::Lenient).score(s, "kitchin")[0].rule, MatchRule::Typo);
}

TEST(Inflection, CorpusWordsWordNetLacksAreBasesButFormsAreNot) {
    ScoringSettings settings;
    settings.rules = RuleSet::Loose;
    settings.vocabulary = {"zorp", "rang"};  // a made-up name of the corpus, and the past of ring
    const KeywordScorer with_corpus(settings);
    EXPECT_EQ(with_corpus.score(sentence_of("zorp"), "two zorps")[0].rule, MatchRule::Inflection);
    EXPECT_EQ(scorer(RuleSet::Loose).score(sentence_of("zorp"), "two zorps")[0].rule, MatchRule::None);
    EXPECT_EQ(with_corpus.score(sentence_of("rang"), "ranged")[0].rule, MatchRule::None);
    EXPECT_EQ(with_corpus.score(sentence_of("rang"), "rung")[0].rule, MatchRule::Inflection);  // both forms of ring
}

TEST(Inflection, LemmasNeedARealBaseOfTheRightPartOfSpeech) {
    const Inflections inf = Inflections::read_default();
    EXPECT_GT(inf.irregular_count(), 500u);
    auto has = [&](const std::string& w, const std::string& lemma) {
        const auto l = inf.lemmas(w);
        return std::find(l.begin(), l.end(), lemma) != l.end();
    };
    EXPECT_TRUE(has("windows", "window"));
    EXPECT_TRUE(has("rang", "ring"));
    EXPECT_FALSE(has("shed", "she"));     // she is no verb
    EXPECT_FALSE(has("news", "new"));     // new is no noun or verb
    EXPECT_FALSE(has("feed", "fee"));     // feed is a verb itself
    EXPECT_FALSE(has("evening", "even")); // listed: a noun of its own
    EXPECT_FALSE(has("clothes", "cloth"));
    EXPECT_FALSE(inf.same_lemma("rang", "range"));
    EXPECT_FALSE(inf.same_lemma("hat", "hated"));
    EXPECT_TRUE(inf.same_lemma("hate", "hated"));
}

}  // namespace
}  // namespace avsi::analysis
