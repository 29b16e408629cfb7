// The corpus keyword audit (protocols/corpus/keyword-audit.csv, written by
// scripts/make-keyword-audit): strict credits only the same spoken word, so
// the corpus lists no grammatical-number alternate unless the audit keeps it
// with a reason; every removed alternate is wrong under strict and right
// under loose (its inflection rule), with the real corpus and scorer.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <set>

#include "avsi/analysis/scoring.h"
#include "avsi/core/corpus.h"
#include "avsi/core/csv.h"

using namespace avsi;
using namespace avsi::analysis;

namespace {

const std::filesystem::path kCorpusDir = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus";

KeywordScorer make_scorer(RuleSet set, const Corpus& corpus) {
    ScoringSettings s;
    s.rules = set;
    s.vocabulary = corpus_vocabulary(corpus);
    return KeywordScorer(s);
}

// The sentence's own text with keyword `index` (1-based) replaced by `word`.
std::string answer_with(const Sentence& sentence, std::size_t index, const std::string& word) {
    std::string text = sentence.text;
    const std::string& keyword = sentence.keywords[index - 1].word;
    const auto at = text.find(keyword);
    EXPECT_NE(at, std::string::npos) << sentence.id << ": " << keyword;
    if (at != std::string::npos) text.replace(at, keyword.size(), word);
    return text;
}

}  // namespace

TEST(KeywordAudit, BoyForBoysIsWrongUnderStrictAndRightUnderLoose) {
    const Corpus corpus = read_corpus(kCorpusDir / "sentences.csv");
    const Sentence& s001 = corpus.sentence("s001");  // The boy fell from the window.
    ASSERT_EQ(s001.keywords[0].word, "boy");
    EXPECT_TRUE(s001.keywords[0].alternates.empty());
    const auto strict = make_scorer(RuleSet::Strict, corpus).score(s001, "the boys fell from the window");
    const auto loose = make_scorer(RuleSet::Loose, corpus).score(s001, "the boys fell from the window");
    EXPECT_FALSE(strict[0].correct);
    EXPECT_EQ(strict[0].rule, MatchRule::None);
    EXPECT_TRUE(loose[0].correct);
    EXPECT_EQ(loose[0].rule, MatchRule::Inflection);
    // The other two keywords are unaffected.
    EXPECT_TRUE(strict[1].correct && strict[2].correct);
}

TEST(KeywordAudit, EveryTestKeywordIsAuditedAndTheCorpusFollowsTheDecisions) {
    const Corpus corpus = read_corpus(kCorpusDir / "sentences.csv");
    const CsvTable audit = read_csv(kCorpusDir / "keyword-audit.csv");
    const auto col = [&](const char* name) { return audit.require_column(name); };
    const std::size_t c_sentence = col("sentence"), c_list = col("list"), c_index = col("keyword_index"),
                      c_keyword = col("keyword"), c_alternate = col("alternate"), c_decision = col("decision"),
                      c_under = col("credited_under"), c_reason = col("reason");
    const std::set<std::string> test_lists = {"1", "2", "3", "4", "5", "6"};
    std::set<std::pair<std::string, std::string>> audited_test_keywords;
    std::size_t removed = 0, kept = 0;
    const KeywordScorer strict = make_scorer(RuleSet::Strict, corpus), loose = make_scorer(RuleSet::Loose, corpus);
    for (const auto& r : audit.rows) {
        SCOPED_TRACE("keyword-audit.csv:" + std::to_string(r.line));
        const Sentence& sentence = corpus.sentence(r.fields[c_sentence]);
        EXPECT_EQ(sentence.list, r.fields[c_list]);
        const std::size_t index = std::stoul(r.fields[c_index]);
        ASSERT_GE(index, 1u);
        ASSERT_LE(index, sentence.keywords.size());
        const Keyword& keyword = sentence.keywords[index - 1];
        EXPECT_EQ(keyword.word, r.fields[c_keyword]);
        if (test_lists.count(sentence.list)) audited_test_keywords.insert({sentence.id, r.fields[c_index]});
        const std::string& alternate = r.fields[c_alternate];
        const std::string& decision = r.fields[c_decision];
        const bool listed = std::find(keyword.alternates.begin(), keyword.alternates.end(), alternate) !=
                            keyword.alternates.end();
        if (decision == "none listed") {
            EXPECT_TRUE(alternate.empty());
        } else if (decision == "kept") {
            ++kept;
            EXPECT_TRUE(listed) << alternate;
            EXPECT_EQ(r.fields[c_under], "strict");
            EXPECT_FALSE(r.fields[c_reason].empty());
        } else {
            ASSERT_EQ(decision, "removed");
            ++removed;
            EXPECT_FALSE(listed) << alternate;
            EXPECT_EQ(r.fields[c_under], "loose");
            const std::string answer = answer_with(sentence, index, alternate);
            const auto s = strict.score(sentence, answer);
            const auto l = loose.score(sentence, answer);
            EXPECT_FALSE(s[index - 1].correct) << answer;
            EXPECT_TRUE(l[index - 1].correct) << answer;
            EXPECT_EQ(l[index - 1].rule, MatchRule::Inflection) << answer;
        }
    }
    // The 270 keywords of the six test lists, each audited.
    std::size_t test_keywords = 0;
    for (const auto& s : corpus.sentences)
        if (test_lists.count(s.list)) test_keywords += s.keywords.size();
    EXPECT_EQ(test_keywords, 270u);
    EXPECT_EQ(audited_test_keywords.size(), 270u);
    EXPECT_GT(removed, 100u);
    EXPECT_GT(kept, 0u);
    // No alternate the audit does not list.
    for (const auto& s : corpus.sentences)
        for (std::size_t i = 0; i < s.keywords.size(); ++i)
            for (const auto& alternate : s.keywords[i].alternates) {
                bool found = false;
                for (const auto& r : audit.rows)
                    found |= r.fields[c_sentence] == s.id && r.fields[c_index] == std::to_string(i + 1) &&
                             r.fields[c_alternate] == alternate && r.fields[c_decision] == "kept";
                EXPECT_TRUE(found) << s.id << " " << s.keywords[i].word << "|" << alternate;
            }
}
