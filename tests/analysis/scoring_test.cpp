// Keyword scoring: normalisation, each rule and their order, the recorded
// rule, the rule sets, overrides, the audit, the agreement with a second
// scorer and the output files.
#include <array>
#include <filesystem>
#include <ostream>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "avsi/analysis/scores.h"
#include "avsi/analysis/scoring.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

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

const KeywordScorer& scorer(RuleSet set = RuleSet::Lenient) {
    static const std::array<KeywordScorer, 3> scorers = [] {
        auto make = [](RuleSet r) {
            ScoringSettings s;
            s.rules = r;
            return KeywordScorer(s);
        };
        return std::array<KeywordScorer, 3>{make(RuleSet::Strict), make(RuleSet::Loose), make(RuleSet::Lenient)};
    }();
    return scorers[std::size_t(set)];
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
    EXPECT_TRUE(table.same_group("bear", "bare"));
    EXPECT_TRUE(table.same_group("4", "for"));  // "four" is stored as 4
    EXPECT_FALSE(table.same_group("bear", "beer"));
    EXPECT_FALSE(table.same_group("been", "bean"));  // not General American
    EXPECT_FALSE(table.same_group("what", "watt"));
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
    const auto lenient = scorer(RuleSet::Lenient).score(s, c.response);
    const auto strict = scorer(RuleSet::Strict).score(s, c.response);
    ASSERT_EQ(lenient.size(), 1u);
    EXPECT_EQ(rule_name(lenient[0].rule), std::string(rule_name(c.lenient)));
    EXPECT_EQ(lenient[0].correct, c.lenient != MatchRule::None);
    EXPECT_EQ(rule_name(strict[0].rule), std::string(rule_name(c.strict)));
}

INSTANTIATE_TEST_SUITE_P(
    Rules, EachRule,
    ::testing::Values(RuleCase{"dog", {}, "the Dog barked", MatchRule::Exact, MatchRule::Exact},
                      RuleCase{"seven", {}, "7 days", MatchRule::Number, MatchRule::Number},
                      RuleCase{"mailman", {"postman"}, "the postman came", MatchRule::Alternate, MatchRule::Alternate},
                      RuleCase{"bear", {}, "a bare tree", MatchRule::Homophone, MatchRule::Homophone},
                      RuleCase{"two", {}, "too late", MatchRule::Homophone, MatchRule::Homophone},
                      RuleCase{"barked", {}, "it was barking", MatchRule::Inflection, MatchRule::None},
                      RuleCase{"garden", {}, "in the gardens", MatchRule::Inflection, MatchRule::None},
                      RuleCase{"kitchen", {}, "the kitchne", MatchRule::Typo, MatchRule::None},
                      RuleCase{"kitchen", {}, "the kitchin", MatchRule::Typo, MatchRule::None},
                      RuleCase{"cat", {}, "a cot", MatchRule::None, MatchRule::None},
                      RuleCase{"kitchen", {}, "the kitten", MatchRule::None, MatchRule::None},
                      RuleCase{"kitchen", {}, "", MatchRule::None, MatchRule::None}));

TEST(RuleOrder, ExactBeatsInflectionAcrossKeywords) {
    // Rule by rule: "walked" is taken by keyword 2 (exact) before keyword 1
    // may take it as an inflection.
    const Sentence s = make_sentence("s", {{"walk", {}}, {"walked", {}}});
    const auto m = scorer().score(s, "he walked");
    EXPECT_EQ(m[0].rule, MatchRule::None);
    EXPECT_EQ(m[1].rule, MatchRule::Exact);
    const auto both = scorer().score(s, "walked walking");
    EXPECT_EQ(both[0].rule, MatchRule::Inflection);
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

TEST(Strictness, LooseAndLenientDifferOnlyOnTypos) {
    const Sentence s = make_sentence("s", {{"garden", {"yard"}}, {"flowers", {}}, {"morning", {}}});
    const std::vector<std::string> responses = {
        "the garden flowers this morning", "the gardne flower in the mourning", "yard flowrs mornin",
        "gardens flowers", "garde flower morning", "nothing", "the guarden flowers morning"};
    int differing = 0;
    for (const auto& r : responses) {
        const auto a = scorer(RuleSet::Lenient).score(s, r);
        const auto b = scorer(RuleSet::Loose).score(s, r);
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

TEST(Strictness, StrictAndLooseDifferOnlyOnInflections) {
    const Sentence s = make_sentence("s", {{"boys", {}}, {"helped", {}}, {"window", {}}});
    const std::vector<std::string> responses = {"the boys helped at the window", "a boy helps the windows",
                                                "boy helping window", "toys yelped widow", ""};
    int differing = 0;
    for (const auto& r : responses) {
        const auto a = scorer(RuleSet::Loose).score(s, r);
        const auto b = scorer(RuleSet::Strict).score(s, r);
        for (std::size_t i = 0; i < a.size(); ++i) {
            SCOPED_TRACE(r + " / keyword " + std::to_string(i + 1));
            if (a[i].rule == MatchRule::Inflection) {
                EXPECT_FALSE(b[i].correct);
                ++differing;
            } else {
                EXPECT_EQ(a[i].rule, b[i].rule);
                EXPECT_EQ(a[i].correct, b[i].correct);
            }
        }
    }
    EXPECT_EQ(differing, 5);
}

TEST(RuleSets, NamesParseAndSetsAreNested) {
    EXPECT_EQ(rule_set_names(), (std::vector<std::string>{"strict", "loose", "lenient"}));
    EXPECT_EQ(rule_set_names(), protocol_rule_sets());  // the protocol loader accepts exactly these
    Protocol p;
    p.scoring.rules = "loose";
    p.scoring.homophones = "rp.csv";
    EXPECT_EQ(scoring_settings(p).rules, RuleSet::Loose);
    EXPECT_EQ(scoring_settings(p).homophones, "rp.csv");
    for (RuleSet set : kRuleSets) EXPECT_EQ(parse_rule_set(rule_set_name(set)), set);
    EXPECT_FALSE(parse_rule_set("strikt"));
    for (MatchRule rule : {MatchRule::Exact, MatchRule::Number, MatchRule::Alternate, MatchRule::Variant,
                           MatchRule::Homophone})
        EXPECT_TRUE(rule_set_allows(RuleSet::Strict, rule)) << rule_name(rule);
    EXPECT_FALSE(rule_set_allows(RuleSet::Strict, MatchRule::Inflection));
    EXPECT_TRUE(rule_set_allows(RuleSet::Loose, MatchRule::Inflection));
    EXPECT_FALSE(rule_set_allows(RuleSet::Loose, MatchRule::Typo));
    EXPECT_TRUE(rule_set_allows(RuleSet::Lenient, MatchRule::Typo));
}

TEST(Kappa, MatchesHandComputation) {
    // 2x2: both 1: 20, a only: 5, b only: 10, neither: 15 (n = 50).
    // po = 35/50 = .7; pa = 25/50 = .5, pb = 30/50 = .6; pe = .5*.6 + .5*.4 = .5;
    // kappa = (.7 - .5) / (1 - .5) = .4.
    EXPECT_NEAR(*cohens_kappa(20, 5, 10, 15), 0.4, 1e-12);
    EXPECT_NEAR(*cohens_kappa(10, 0, 0, 10), 1.0, 1e-12);
    EXPECT_FALSE(cohens_kappa(7, 0, 0, 0));  // one verdict throughout: chance agreement is 1
    EXPECT_FALSE(cohens_kappa(0, 0, 0, 0));
    // One side with one verdict throughout, the other varying: the formula gives 0, the doc says NA.
    EXPECT_FALSE(cohens_kappa(5, 7, 0, 0));  // a: yes throughout; b: 5 yes, 7 no
    EXPECT_FALSE(cohens_kappa(0, 0, 4, 8));  // a: no throughout; b: 4 yes, 8 no
    EXPECT_NEAR(*cohens_kappa(3, 0, 0, 9), 1.0, 1e-12);  // both vary and agree

}

class ScoreFiles : public ::testing::Test {
protected:
    void SetUp() override {
        dir = test::temp_dir("scoring_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
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
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", {}, {}, {}};
    s.scoring.rules = RuleSet::Lenient;
    const auto result = score_files(s).scoring;
    EXPECT_EQ(result.trials_scored, 4u);  // the warmup trial is not scored
    const CsvTable keywords = read_csv(dir / "out" / "keywords.csv");
    ASSERT_EQ(keywords.rows.size(), 12u);
    const auto c_rule = keywords.require_column("rule");
    EXPECT_EQ(keywords.rows[0].fields[c_rule], "alternate");  // dogs
    EXPECT_EQ(keywords.rows[1].fields[c_rule], "inflection");  // barking
    EXPECT_EQ(keywords.rows[2].fields[c_rule], "alternate");  // postman
    EXPECT_EQ(keywords.rows[3].fields[c_rule], "number");     // 7 = seven
    EXPECT_EQ(keywords.rows[5].fields[c_rule], "typo");       // kitchne
    const CsvTable scores = read_csv(dir / "out" / "scores.csv");
    ASSERT_EQ(scores.rows.size(), 4u);
    EXPECT_EQ(scores.header,
              (std::vector<std::string>{"subject", "condition", "keywords", "correct", "percent", "rule_set"}));
    EXPECT_EQ(scores.rows[0].fields, (std::vector<std::string>{"p1", "audio", "3", "3", "100", "lenient"}));
    EXPECT_EQ(scores.rows[3].fields, (std::vector<std::string>{"p2", "audio", "3", "0", "0", "lenient"}));
    EXPECT_EQ(read_scores(dir / "out" / "scores.csv").rule_set, "lenient");
    ScoreFilesSettings strict = s;
    strict.scoring.rules = RuleSet::Strict;
    strict.out_dir = dir / "strict";
    const auto strict_result = score_files(strict).scoring;
    EXPECT_FALSE(strict_result.keywords[5].match.correct);  // kitchne: no typo credit
    EXPECT_FALSE(strict_result.keywords[1].match.correct);  // barking: no inflection credit
}

TEST_F(ScoreFiles, OverridesAreAppliedAndLogged) {
    write_text_file(dir / "overrides.csv",
                    "subject,trial,keyword_index,correct,reason\n"
                    "p2,1,2,1,\"wrote 'barks' on paper, entered late\"\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", dir / "overrides.csv", {}, {}};
    const auto result = score_files(s).scoring;
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
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", dir / "overrides.csv", {}, {}};
    EXPECT_THROW(score_files(s), InputError);
}

TEST_F(ScoreFiles, AuditListsNonExactCreditsAndEditsIntoOverrides) {
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", {}, {}, {}};
    s.scoring.rules = RuleSet::Strict;
    score_files(s);
    const CsvTable audit = read_csv(dir / "out" / "audit.csv");
    EXPECT_EQ(audit.header, (std::vector<std::string>{"subject", "trial", "sentence", "keyword_index", "keyword",
                                                      "response_word", "rule", "rule_set", "correct", "reason",
                                                      "condition", "response"}));
    // Strict credits dogs and postman (alternates) and 7 (number); only loose
    // credits barking, only lenient kitchne.
    std::vector<std::string> got;
    for (const auto& r : audit.rows)
        got.push_back(fmt::format("{} {} {} {} {} {} {}", r.fields[0], r.fields[1], r.fields[3], r.fields[5],
                                  r.fields[6], r.fields[7], r.fields[8]));
    EXPECT_EQ(got, (std::vector<std::string>{"p1 2 1 dogs alternate strict 1", "p1 2 3 postman alternate strict 1",
                                             "p1 3 1 7 number strict 1", "p1 2 2 barking inflection loose 0",
                                             "p1 3 3 kitchne typo lenient 0"}));

    // The researcher credits kitchne (correct 1 and a reason) and leaves the
    // other lines as they are: the edited audit is the overrides file.
    std::string edited = read_text_file(dir / "out" / "audit.csv");
    const std::string from = "p1,3,s2,3,kitchen,kitchne,typo,lenient,0,,";
    ASSERT_NE(edited.find(from), std::string::npos) << edited;
    edited.replace(edited.find(from), from.size(), "p1,3,s2,3,kitchen,kitchne,typo,lenient,1,obvious typo,");
    write_text_file(dir / "audit-edited.csv", edited);
    s.overrides = dir / "audit-edited.csv";
    s.out_dir = dir / "reviewed";
    const auto reviewed = score_files(s).scoring;
    ASSERT_EQ(reviewed.overrides.size(), 1u);
    EXPECT_EQ(reviewed.overrides[0].keyword, "kitchen");
    EXPECT_TRUE(reviewed.keywords[5].match.correct);
    EXPECT_EQ(reviewed.keywords[5].override_reason, "obvious typo");
    EXPECT_FALSE(reviewed.keywords[1].match.correct);  // barking: left as strict scored it
}

TEST_F(ScoreFiles, OverrideChangingAVerdictNeedsAReason) {
    write_text_file(dir / "overrides.csv",
                    "subject,trial,keyword_index,correct,reason\n"
                    "p1,2,1,1,\n"   // confirms the automatic credit: fine without a reason
                    "p1,2,2,1,\n");  // changes barked to correct without a reason
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", dir / "overrides.csv", {}, {}};
    try {
        score_files(s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        ASSERT_EQ(e.diagnostics().size(), 1u) << e.what();
        EXPECT_EQ(e.first().line, 3);
        EXPECT_EQ(e.first().field, "reason");
        EXPECT_NE(std::string(e.what()).find("overrides.csv"), std::string::npos) << e.what();
    }
}

TEST_F(ScoreFiles, AgreementWithASecondScorerPerRuleSet) {
    // The second scorer credits the typo kitchne, marks barking wrong, and
    // (wrongly) credits barked in p2's "a dog".
    write_text_file(dir / "second.csv",
                    "subject,trial,keyword_index,correct\n"
                    "p1,2,1,1\np1,2,2,0\np1,2,3,1\n"
                    "p1,3,1,1\np1,3,2,1\np1,3,3,1\n"
                    "p2,1,1,1\np2,1,2,1\np2,1,3,0\n"
                    "p2,2,1,0\np2,2,2,0\np2,2,3,0\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", {}, dir / "second.csv", {}};
    const auto result = score_files(s);
    ASSERT_TRUE(result.agreement);
    const auto& rows = result.agreement->rows;
    ASSERT_EQ(rows.size(), 3u);
    // By hand (n = 12; automatic strict 5 correct, loose 6, lenient 7; scorer 7):
    //   strict:  both 5, auto only 0, scorer only 2, neither 5: po = 10/12,
    //            pe = (5*7 + 7*5)/144 = 70/144, kappa = (120-70)/(144-70) = 25/37
    //   loose:   both 5, 1, 2, 4: po = 9/12, pe = (6*7 + 6*5)/144 = 1/2, kappa = 1/2
    //   lenient: both 6, 1, 1, 4: po = 10/12, pe = (7*7 + 5*5)/144 = 74/144,
    //            kappa = (120-74)/(144-74) = 46/70
    EXPECT_EQ(rows[0].scoring, "strict");
    EXPECT_EQ(rows[0].keywords, 12u);
    EXPECT_EQ(rows[0].agreements, 10u);
    EXPECT_NEAR(rows[0].percent_agreement, 100.0 * 10 / 12, 1e-9);
    EXPECT_NEAR(*rows[0].kappa, 25.0 / 37.0, 1e-12);
    EXPECT_EQ(rows[1].scoring, "loose");
    EXPECT_EQ(rows[1].agreements, 9u);
    EXPECT_NEAR(*rows[1].kappa, 0.5, 1e-12);
    EXPECT_EQ(rows[2].scoring, "lenient");
    EXPECT_NEAR(*rows[2].kappa, 46.0 / 70.0, 1e-12);
    EXPECT_EQ(result.agreement->disagreements.size(), 2u + 3u + 2u);

    const CsvTable agreement = read_csv(dir / "out" / "agreement.csv");
    ASSERT_EQ(agreement.rows.size(), 3u);
    EXPECT_EQ(agreement.rows[1].fields[agreement.require_column("kappa")], "0.500000");
    const CsvTable disagreements = read_csv(dir / "out" / "disagreements.csv");
    ASSERT_EQ(disagreements.rows.size(), 7u);
    const auto c_keyword = disagreements.require_column("keyword");
    const auto c_scoring = disagreements.require_column("scoring");
    EXPECT_EQ(disagreements.rows[0].fields[c_scoring], "strict");
    EXPECT_EQ(disagreements.rows[0].fields[c_keyword], "kitchen");
    EXPECT_EQ(disagreements.rows[1].fields[c_keyword], "barked");
}

TEST_F(ScoreFiles, SecondScorerRowsMustNameScoredKeywords) {
    write_text_file(dir / "second.csv", "subject,trial,keyword_index,correct\np1,2,1,1\np1,2,1,0\np9,1,1,1\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "responses.csv", dir / "out", {}, dir / "second.csv", {}};
    try {
        score_files(s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        ASSERT_EQ(e.diagnostics().size(), 2u) << e.what();
        EXPECT_EQ(e.diagnostics()[0].line, 3);  // judged twice
        EXPECT_EQ(e.diagnostics()[1].line, 4);  // no such subject
        EXPECT_NE(std::string(e.what()).find("second.csv"), std::string::npos);
    }
}

TEST_F(ScoreFiles, UnknownSentenceNamesTheLine) {
    write_text_file(dir / "bad.csv",
                    "subject,session,trial,phase,condition,list,sentence,response\n"
                    "p1,1,1,test,audio,1,s3,the dog\n");
    ScoreFilesSettings s{dir / "sentences.csv", dir / "bad.csv", dir / "out", {}, {}, {}};
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
