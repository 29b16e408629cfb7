// Keyword alternates proposed by `avsi corpus import` for review, from the
// scoring module's inflection and spelling-variant tables (issue 20).
#include <gtest/gtest.h>

#include <filesystem>

#include "avsi/analysis/alternates.h"
#include "avsi/core/corpus.h"
#include "avsi/core/keyword_proposals.h"
#include "avsi/core/word_table.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

namespace avsi::analysis {
namespace {

std::string proposals(const AlternateFinder& f, const std::string& word) {
    std::string out;
    for (const auto& p : f.propose(word)) out += (out.empty() ? "" : ", ") + p.word + " (" + p.reason + ")";
    return out;
}

TEST(Alternates, InflectionsAndSpellingVariantsFromTheScoringTables) {
    const auto finder = AlternateFinder::load_default();
    EXPECT_EQ(proposals(*finder, "canoe"), "canoes (plural)");
    EXPECT_EQ(proposals(*finder, "planks"), "plank (singular)");
    // A plural that is also a noun in WordNet (the game of bowls) gets its singular, not a plural of a plural.
    EXPECT_EQ(proposals(*finder, "bowls"), "bowl (singular)");
    // A plural the rules make but nobody writes is not proposed: woman → women (WordNet's -man → -men).
    EXPECT_EQ(proposals(*finder, "woman"), "women (plural)");
    EXPECT_EQ(proposals(*finder, "human"), "humans (plural)");
    EXPECT_EQ(proposals(*finder, "birch"), "birches (plural)");
    EXPECT_EQ(proposals(*finder, "slid"), "slide (base form)");
    EXPECT_NE(proposals(*finder, "child").find("children (irregular form)"), std::string::npos)
        << proposals(*finder, "child");
    const std::string colour = proposals(*finder, "colour");
    EXPECT_NE(colour.find("color (spelling variant)"), std::string::npos) << colour;
    EXPECT_NE(colour.find("colours (plural)"), std::string::npos) << colour;
    // Not every spelling is a form: evening is not even + ing, and function words get nothing.
    EXPECT_EQ(proposals(*finder, "evening").find("even "), std::string::npos) << proposals(*finder, "evening");
    EXPECT_EQ(proposals(*finder, "7"), "");
}

TEST(Alternates, ImportMarksThemForReviewNotForScoring) {
    ImportSettings s;
    s.min_syllables = 0;
    s.max_syllables = 0;
    s.alternates = AlternateFinder::load_default()->proposer();
    ImportOutcome o = import_sentences({"The birch canoe slid on the smooth planks."}, s);
    ASSERT_EQ(o.corpus.sentences.size(), 1u);
    const Sentence& sentence = o.corpus.sentences[0];
    for (const auto& k : sentence.keywords) EXPECT_TRUE(k.alternates.empty()) << k.word;  // not accepted
    EXPECT_EQ(sentence.review, "birch|birches;canoe|canoes;planks|plank");
    EXPECT_NE(o.report.find("canoe: proposed alternates, to review: canoes (plural)"), std::string::npos) << o.report;
    // The review column survives writing and reading the corpus.
    const auto dir = test::temp_dir("alternates");
    o.corpus.path = dir / "s.csv";
    write_corpus(dir / "s.csv", o.corpus);
    const Corpus back = read_corpus(dir / "s.csv");
    EXPECT_EQ(back.sentences[0].review, sentence.review);
    EXPECT_NE(read_text_file(dir / "s.csv").find(",review\n"), std::string::npos);
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace avsi::analysis
