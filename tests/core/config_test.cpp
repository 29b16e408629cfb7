#include "avsi/core/config.h"

#include <gtest/gtest.h>

#include "avsi/core/error.h"

namespace avsi {
namespace {

std::vector<Diagnostic> problems_of(const DiagnosticList& list) {
    try {
        list.throw_if_any();
    } catch (const InputError& e) {
        return e.diagnostics();
    }
    return {};
}

TEST(Config, TypedGettersReturnValuesAndRememberLocations) {
    const ConfigSection root = parse_config(
        "[vocoder]\nbands = 3\nlow_hz = 100.5\nname = \"noise\"\non = true\nlist = [\"a\", \"b\"]\n",
        "t.toml");
    DiagnosticList problems;
    const ConfigSection* v = root.get_table("vocoder", problems);
    ASSERT_NE(v, nullptr);
    EXPECT_EQ(v->name(), "vocoder");
    EXPECT_EQ(v->get_int("bands", 0, 1, 32, problems), 3);
    EXPECT_DOUBLE_EQ(v->get_number("low_hz", 0, 0, 1e5, problems), 100.5);
    EXPECT_DOUBLE_EQ(v->get_number("bands", 0, 0, 1e5, problems), 3.0);
    EXPECT_EQ(v->get_string("name", "", problems), "noise");
    EXPECT_TRUE(v->get_bool("on", false, problems));
    EXPECT_EQ(v->get_string_list("list", problems), (std::vector<std::string>{"a", "b"}));
    EXPECT_EQ(v->get_int("absent", 7, 1, 32, problems), 7);
    EXPECT_TRUE(problems.empty());
    EXPECT_EQ(v->find("low_hz")->line, 3);
    EXPECT_EQ(v->find("low_hz")->column, 10);
    EXPECT_EQ(v->find("low_hz")->key_column, 1);
    EXPECT_EQ(v->keys(), (std::vector<std::string>{"bands", "low_hz", "name", "on", "list"}));
}

TEST(Config, WrongTypesAndRangesAreReportedWithFieldAndLocation) {
    const ConfigSection root =
        parse_config("[vocoder]\nbands = \"three\"\nlow_hz = -1\nmode = \"nois\"\n", "study.toml");
    DiagnosticList problems;
    const ConfigSection* v = root.get_table("vocoder", problems);
    ASSERT_NE(v, nullptr);
    EXPECT_EQ(v->get_int("bands", 3, 1, 32, problems), 3);
    EXPECT_EQ(v->get_number("low_hz", 100, 0, 20000, problems), 100);
    EXPECT_EQ(v->get_choice("mode", {"noise", "sine"}, "noise", problems), "noise");
    const auto d = problems_of(problems);
    ASSERT_EQ(d.size(), 3u);
    EXPECT_EQ(d[0].format(), "study.toml:2:9: error: vocoder.bands: expected an integer in [1, 32], got \"three\"");
    EXPECT_EQ(d[1].format(), "study.toml:3:10: error: vocoder.low_hz: expected a number in [0, 20000], got -1");
    EXPECT_EQ(d[2].format(),
              "study.toml:4:8: error: vocoder.mode: expected \"noise\" or \"sine\", got \"nois\" (did you mean \"noise\"?)");
}

TEST(Config, UnknownKeysGetDidYouMeanFromTheKeysRead) {
    const ConfigSection root = parse_config("[design]\nlists = 6\nwarmpu = 15\nzzzzzz = 1\n", "p.toml");
    DiagnosticList problems;
    const ConfigSection* d = root.get_table("design", problems);
    ASSERT_NE(d, nullptr);
    d->get_int("lists", 6, 1, 100, problems);
    d->get_int("warmup", 0, 0, 100, problems);
    d->check_unknown_keys(problems);
    const auto items = problems_of(problems);
    ASSERT_EQ(items.size(), 2u);
    EXPECT_EQ(items[0].format(), "p.toml:3:1: error: design.warmpu: unknown key (did you mean \"warmup\"?)");
    EXPECT_EQ(items[1].format(), "p.toml:4:1: error: design.zzzzzz: unknown key");
}

TEST(Config, ArraysOfTablesAreNamedByIndex) {
    const ConfigSection root =
        parse_config("[[condition]]\nname = \"a\"\n[[condition]]\nname = 5\n", "c.toml");
    DiagnosticList problems;
    const auto tables = root.get_table_array("condition", problems);
    ASSERT_EQ(tables.size(), 2u);
    EXPECT_EQ(tables[0]->get_string("name", "", problems), "a");
    tables[1]->get_string("name", "", problems);
    const auto d = problems_of(problems);
    ASSERT_EQ(d.size(), 1u);
    EXPECT_EQ(d[0].format(), "c.toml:4:8: error: condition[2].name: expected a string, got 5");
    EXPECT_EQ(tables[1]->line(), 3);
}

TEST(Config, RequireReportsMissingKeysAtTheSection) {
    const ConfigSection root = parse_config("\n[corpus]\nvoice = \"en\"\n", "r.toml");
    DiagnosticList problems;
    const ConfigSection* c = root.get_table("corpus", problems);
    ASSERT_NE(c, nullptr);
    EXPECT_FALSE(c->require("sentences", problems));
    EXPECT_TRUE(c->require("voice", problems));
    const auto d = problems_of(problems);
    ASSERT_EQ(d.size(), 1u);
    EXPECT_EQ(d[0].field, "corpus.sentences");
    EXPECT_EQ(d[0].line, 2);
}

TEST(Config, SyntaxErrorsCarryLineAndColumn) {
    try {
        parse_config("a = 1\nb = = 2\n", "s.toml");
        FAIL() << "expected a parse error";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, "s.toml");
        EXPECT_EQ(e.first().line, 2);
        EXPECT_GT(e.first().column, 0);
        EXPECT_NE(e.first().message.find("invalid TOML"), std::string::npos);
    }
}

}  // namespace
}  // namespace avsi
