#include "avsi/core/csv.h"

#include <gtest/gtest.h>

#include "avsi/core/error.h"

namespace avsi {
namespace {

TEST(Csv, ParsesQuotedFieldsAndKeepsLineNumbers) {
    const auto t = parse_csv("id,text\n# comment\na,\"x, \"\"y\"\"\"\nb,\"two\nlines\"\nc,z\n", "t.csv");
    ASSERT_EQ(t.header, (std::vector<std::string>{"id", "text"}));
    ASSERT_EQ(t.rows.size(), 3u);
    EXPECT_EQ(t.rows[0].line, 3);
    EXPECT_EQ(t.rows[0].fields[1], "x, \"y\"");
    EXPECT_EQ(t.rows[1].fields[1], "two\nlines");
    EXPECT_EQ(t.rows[2].line, 6);
}

TEST(Csv, WrongFieldCountNamesTheLine) {
    try {
        parse_csv("a,b\n1,2\n3\n", "t.csv");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 3);
        EXPECT_STREQ(e.what(), "t.csv:3: error: expected 2 fields as in the header, got 1");
    }
}

TEST(Csv, UnclosedQuoteIsAnError) { EXPECT_THROW(parse_csv("a\n\"open\n", "t.csv"), InputError); }

TEST(Csv, MissingColumnSuggestsCloseName) {
    const auto t = parse_csv("id,keywrds\n", "t.csv");
    try {
        t.require_column("keywords");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("did you mean 'keywrds'"), std::string::npos);
    }
}

TEST(Csv, EscapeRoundTrips) {
    const std::vector<std::string> fields{"plain", "with,comma", "with \"quote\"", "multi\nline"};
    const auto t = parse_csv("h1,h2,h3,h4\n" + csv_line(fields), "t.csv");
    EXPECT_EQ(t.rows.at(0).fields, fields);
}

TEST(Numbers, WholeFieldMustParse) {
    EXPECT_EQ(parse_double(" 1.5 "), 1.5);
    EXPECT_EQ(parse_double("-2e-3"), -2e-3);
    EXPECT_FALSE(parse_double("1.5x"));
    EXPECT_FALSE(parse_double(""));
    EXPECT_FALSE(parse_double("nan"));
    EXPECT_EQ(parse_int("42"), 42);
    EXPECT_FALSE(parse_int("4.2"));
}

}  // namespace
}  // namespace avsi
