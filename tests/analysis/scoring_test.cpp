// Keyword scoring: normalisation, each rule and their order, the recorded
// rule, strict vs lenient, overrides and the output files.
#include <filesystem>
#include <ostream>

#include <gtest/gtest.h>

#include "avsi/analysis/scoring.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::analysis {
namespace {

using Words = std::vector<std::string>;

Sentence make_sentence(const std::string& id, std::vector<Keyword> keywords) {
    Sentence s;
    s.id = id;
    s.text = id;
    s.keywords = std::move(keywords);
    return s;
}

KeywordScorer& scorer(bool strict = false) {
    static KeywordScorer lenient([] {
        ScoringSettings s;
        s.strict = false;
        return s;
    }());
    static KeywordScorer strict_scorer([] {
        ScoringSettings s;
        s.strict = true;
        return s;
    }());
    return strict ? strict_scorer : lenient;
}

TEST(Normalize, CasePunctuationAndDiacritics) {
    EXPECT_EQ(normalize_words("The CAFÉ, naïve!  Straße—über"), (Words{"the", "cafe", "naive", "strasse", "uber"}));
    EXPECT_EQ(normalize_words("Łódź “quoted” mail-man"), (Words{"lodz", "quoted", "mail", "man"}));
}

TEST(Normalize, NumbersBothWays) {
    EXPECT_EQ(normalize_words("seven"), Words{"7"});
    EXPECT_EQ(normalize_words("7"), Words{"7"});
    EXPECT_EQ(normalize_words("twenty-one dogs"), (Words{"21", "dogs"}));
    EXPECT_EQ(normalize_words("one hundred and five"), Words{"105"});
    EXPECT_EQ(normalize_words("two thousand and twelve"), Words{"2012"});
    EXPECT_EQ(normalize_words("1,000 and one"), (Words{"1000", "and", "1"}));
    EXPECT_EQ(normalize_words("one two three"), (Words{"1", "2", "3"}));
    EXPECT_EQ(normalize_words("the twenty-first floor"), (Words{"the", "21st", "floor"}));
    EXPECT_EQ(normalize_words("first"), Words{"1st"});
}

TEST(Normalize, ContractionsExpanded) {
    EXPECT_EQ(normalize_words("Don't"), (Words{"do", "not"}));
    EXPECT_EQ(normalize_words("won't can't"), (Words{"will", "not", "can", "not"}));
    EXPECT_EQ(normalize_words("it’s they're I'm we'll you've she'd"),
              (Words{"it", "is", "they", "are", "i", "am", "we", "will", "you", "have", "she", "would"}));
    EXPECT_EQ(normalize_words("the dog's bone"), (Words{"the", "dog", "bone"}));
}

TEST(Homophones, ShippedTableLoadsWithHundredsOfGroups) {
    const auto table = HomophoneTable::read(AVSI_PROTOCOLS_DIR "/homophones.csv");
    EXPECT_GT(table.group_count(), 300u);
    EXPECT_TRUE(table.are_homophones("bear", "bare"));
    EXPECT_TRUE(table.are_homophones("4", "for"));  // "four" is stored as 4
    EXPECT_FALSE(table.are_homophones("bear", "beer"));
}

struct RuleCase {
    const char* keyword;
    std::vector<std::string> alternates;
    const char* response;
    MatchRule lenient;
    MatchRule strict;
};

// gtest prints a failing case by this (not as a byte dump).
void PrintTo(const RuleCase& c, std::ostream* os) {
    *os << "keyword \"" << c.keyword << "\", response \"" << c.response << "\"";
}

class EachRule : public ::testing::TestWithParam<RuleCase> {};

TEST_P(EachRule, RecordsTheRuleThatMatched) {
    const RuleCase& c = GetParam();
    SCOPED_TRACE(std::string(c.keyword) + " <- " + c.response);
    const Sentence s = make_sentence("s1", {{c.keyword, c.alternates}});
    const auto lenient = scorer(false).score(s, c.response);
    const auto strict = scorer(true).score(s, c.response);
    ASSERT_EQ(lenient.size(), 1u);
    EXPECT_EQ(rule_name(lenient[0].rule), std::string(rule_name(c.lenient)));
    EXPECT_EQ(lenient[0].correct, c.lenient != MatchRule::None);
    EXPECT_EQ(rule_name(strict[0].rule), std::string(rule_name(c.strict)));
}

INSTANTIATE_TEST_SUITE_P(
    Rules, EachRule,
    ::testing::Values(RuleCase{"dog", {}, "the Dog barked", MatchRule::Exact, MatchRule::Exact},
                      RuleCase{"seven", {}, "7 days", MatchRule::Exact, MatchRule::Exact},
                      RuleCase{"mailman", {"postman"}, "the postman came", MatchRule::Alternate, MatchRule::Alternate},
                      RuleCase{"bear", {}, "a bare tree", MatchRule::Homophone, MatchRule::Homophone},
                      RuleCase{"two", {}, "too late", MatchRule::Homophone, MatchRule::Homophone},
                      RuleCase{"barked", {}, "it was barking", MatchRule::Stem, MatchRule::Stem},
                      RuleCase{"garden", {}, "in the gardens", MatchRule::Stem, MatchRule::Stem},
                      RuleCase{"kitchen", {}, "the kitchne", MatchRule::Typo, MatchRule::None},
                      RuleCase{"kitchen", {}, "the kitchin", MatchRule::Typo, MatchRule::None},
                      RuleCase{"cat", {}, "a cot", MatchRule::None, MatchRule::None},
                      RuleCase{"kitchen", {}, "the kitten", MatchRule::None, MatchRule::None},
                      RuleCase{"kitchen", {}, "", MatchRule::None, MatchRule::None}));

TEST(RuleOrder, ExactBeatsStemAcrossKeywords) {
    // Rule by rule: "walked" is taken by keyword 2 (exact) before keyword 1
    // may take it by stem.
    const Sentence s = make_sentence("s", {{"walk", {}}, {"walked", {}}});
    const auto m = scorer().score(s, "he walked");
    EXPECT_EQ(m[0].rule, MatchRule::None);
    EXPECT_EQ(m[1].rule, MatchRule::Exact);
    const auto both = scorer().score(s, "walked walking");
    EXPECT_EQ(both[0].rule, MatchRule::Stem);
    EXPECT_EQ(both[0].matched_word, "walking");
    EXPECT_EQ(both[1].rule, MatchRule::Exact);
}

TEST(RuleOrder, AWordMatchesAtMostOneKeyword) {
    const Sentence s = make_sentence("s", {{"red", {}}, {"red", {}}});
    const auto one = scorer().score(s, "red");
    EXPECT_TRUE(one[0].correct);
    EXPECT_FALSE(one[1].correct);
    const auto two = scorer().score(s, "red and red");
    EXPECT_TRUE(two[0].correct);
    EXPECT_TRUE(two[1].correct);
}

TEST(RuleOrder, ExactPreferredOverAlternateForTheSameKeyword) {
    const Sentence s = make_sentence("s", {{"dog", {"dogs"}}});
    const auto m = scorer().score(s, "dogs and a dog");
    EXPECT_EQ(m[0].rule, MatchRule::Exact);
    EXPECT_EQ(m[0].matched_word, "dog");
}

TEST(RuleOrder, MultiWordKeywordNeedsConsecutiveWords) {
    const Sentence s = make_sentence("s", {{"ice cream", {}}});
    EXPECT_EQ(scorer().score(s, "some ice cream")[0].rule, MatchRule::Exact);
    EXPECT_EQ(scorer().score(s, "cream and ice")[0].rule, MatchRule::None);
}

TEST(Strictness, StrictAndLenientDifferOnlyOnTypos) {
    const Sentence s = make_sentence("s", {{"garden", {"yard"}}, {"flowers", {}}, {"morning", {}}});
    const std::vector<std::string> responses = {
        "the garden flowers this morning", "the gardne flower in the mourning", "yard flowrs mornin",
        "gardens flowers", "garde flower morning", "nothing", "the guarden flowers morning"};
    int differing = 0;
    for (const auto& r : responses) {
        const auto a = scorer(false).score(s, r);
        const auto b = scorer(true).score(s, r);
        for (std::size_t i = 0; i < a.size(); ++i) {
            SCOPED_TRACE(r + " / keyword " + std::to_string(i + 1));
            if (a[i].rule == MatchRule::Typo) {
                EXPECT_FALSE(b[i].correct);
                ++differing;
            } else {
                EXPECT_EQ(a[i].rule, b[i].rule);
                EXPECT_EQ(a[i].correct, b[i].correct);
                EXPECT_EQ(a[i].matched_word, b[i].matched_word);
            }
        }
    }
    EXPECT_GE(differing, 3);
}

class ScoreFiles : public ::testing::Test {
protected:
    void SetUp() override {
        dir = std::filesystem::temp_directory_path() /
              ("avsi_scoring_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
        write_text_file(dir / "sentences.csv",
                        "id,text,keywords\n"
                        "s1,\"The dog barked at the mailman.\",\"dog|dogs;barked;mailman|postman\"\n"
                        "s2,\"Seven kittens slept in the kitchen.\",\"seven;kittens;kitchen\"\n");
        write_text_file(dir / "responses.csv",
                        "subject,session,trial,phase,condition,list,sentence,response\n"
                        "p1,1,1,warmup,audio,0,s1,the dog\n"
                        "p1,1,2,test,audio,1,s1,\"the dogs barking at the postman\"\n"
                        "p1,1,3,test,face,2,s2,\"7 kittens in the kitchne\"\n"
                        "p2,1,1,test,face,1,s1,\"a dog\"\n"
                        "p2,1,2,test,audio,2,s2,\"\"\n");
    }
    void TearDown() override { std::filesystem::remove_all(dir); }
    std::filesystem::path dir;
};

TEST_F(ScoreFiles, WritesKeywordsAndScores) {
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", {}, {}};
    const auto result = score_files(s);
    EXPECT_EQ(result.trials_scored, 4u);  // the warmup trial is not scored
    const CsvTable keywords = read_csv(dir / "out" / "keywords.csv");
    ASSERT_EQ(keywords.rows.size(), 12u);
    const auto c_rule = keywords.require_column("rule");
    EXPECT_EQ(keywords.rows[0].fields[c_rule], "alternate");  // dogs
    EXPECT_EQ(keywords.rows[1].fields[c_rule], "stem");       // barking
    EXPECT_EQ(keywords.rows[2].fields[c_rule], "alternate");  // postman
    EXPECT_EQ(keywords.rows[3].fields[c_rule], "exact");      // 7 = seven
    EXPECT_EQ(keywords.rows[5].fields[c_rule], "typo");       // kitchne
    const CsvTable scores = read_csv(dir / "out" / "scores.csv");
    ASSERT_EQ(scores.rows.size(), 4u);
    EXPECT_EQ(scores.header, (std::vector<std::string>{"subject", "condition", "keywords", "correct", "percent"}));
    EXPECT_EQ(scores.rows[0].fields, (std::vector<std::string>{"p1", "audio", "3", "3", "100"}));
    EXPECT_EQ(scores.rows[3].fields, (std::vector<std::string>{"p2", "audio", "3", "0", "0"}));
    ScoreFilesSettings strict = s;
    strict.scoring.strict = true;
    strict.out_dir = dir / "strict";
    const auto strict_result = score_files(strict);
    EXPECT_FALSE(strict_result.keywords[5].match.correct);
}

TEST_F(ScoreFiles, OverridesAreAppliedAndLogged) {
    write_text_file(dir / "overrides.csv",
                    "subject,trial,keyword_index,correct,reason\n"
                    "p2,1,2,1,\"wrote 'barks' on paper, entered late\"\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", dir / "overrides.csv", {}};
    const auto result = score_files(s);
    ASSERT_EQ(result.overrides.size(), 1u);
    EXPECT_FALSE(result.overrides[0].automatic_correct);
    const CsvTable keywords = read_csv(dir / "out" / "keywords.csv");
    const auto c_reason = keywords.require_column("override_reason");
    const auto c_correct = keywords.require_column("correct");
    const auto c_rule = keywords.require_column("rule");
    EXPECT_EQ(keywords.rows[7].fields[c_reason], "wrote 'barks' on paper, entered late");
    EXPECT_EQ(keywords.rows[7].fields[c_correct], "1");
    EXPECT_EQ(keywords.rows[7].fields[c_rule], "none");  // the automatic rule stays
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / "overrides_applied.csv"));
}

TEST_F(ScoreFiles, OverrideMatchingNothingIsAnError) {
    write_text_file(dir / "overrides.csv", "subject,sentence,keyword_index,correct,reason\np9,s1,1,1,typo\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", dir / "overrides.csv", {}};
    EXPECT_THROW(score_files(s), InputError);
}

TEST_F(ScoreFiles, UnknownSentenceNamesTheLine) {
    write_text_file(dir / "bad.csv",
                    "subject,session,trial,phase,condition,list,sentence,response\n"
                    "p1,1,1,test,audio,1,s3,the dog\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "bad.csv", dir / "out", {}, {}};
    try {
        score_files(s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 2);
        EXPECT_NE(std::string(e.what()).find("bad.csv"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("s3"), std::string::npos);
    }
}

}  // namespace
}  // namespace avsi::analysis
