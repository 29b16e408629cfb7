#include "avsi/core/corpus.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

// `text` as the file `name` in this process's folder (ctest runs each test in a process of its own).
fs::path write_temp(const std::string& name, const std::string& text) {
    static const fs::path dir = test::temp_dir("corpus");
    const fs::path p = dir / name;
    write_text_file(p, text);
    return p;
}

TEST(Corpus, ReadsKeywordsWithAlternatesAndRoundTrips) {
    const auto p = write_temp("c.csv",
                              "id,text,keywords,list\n"
                              "s1,\"The dog barked at night.\",dog|dogs;barked|barking;night,1\n"
                              "s2,She paints the old fence.,paints;old;fence|fences,practice\n");
    const Corpus c = read_corpus(p);
    ASSERT_EQ(c.sentences.size(), 2u);
    EXPECT_EQ(c.sentences[0].keywords.size(), 3u);
    EXPECT_EQ(c.sentences[0].keywords[0].word, "dog");
    EXPECT_EQ(c.sentences[0].keywords[0].alternates, (std::vector<std::string>{"dogs"}));
    EXPECT_EQ(c.sentences[1].list, "practice");
    const auto p2 = p.parent_path() / "c2.csv";
    write_corpus(p2, c);
    const Corpus c2 = read_corpus(p2);
    EXPECT_EQ(c2.sentences[0].keywords[2].word, "night");
    EXPECT_EQ(c2.sentences[1].text, "She paints the old fence.");
    EXPECT_EQ(c.sentence("s2").line, 3);
}

TEST(Corpus, ReportsEveryProblemWithItsLine) {
    const auto p = write_temp("bad.csv",
                              "id,text,keywords\n"
                              "s1,The dog barked.,cat;barked\n"
                              "s1,Another one.,another\n"
                              ",,\n");
    try {
        read_corpus(p);
        FAIL();
    } catch (const InputError& e) {
        ASSERT_GE(e.diagnostics().size(), 4u);
        EXPECT_EQ(e.diagnostics()[0].line, 2);
        EXPECT_EQ(e.diagnostics()[0].field, "keywords");
        EXPECT_EQ(e.diagnostics()[1].line, 3);
        EXPECT_EQ(e.diagnostics()[1].field, "id");
    }
}

}  // namespace
}  // namespace avsi
