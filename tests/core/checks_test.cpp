// The shared input checks (checks.h) and the bounded JSON parse (json.h).
#include "avsi/core/checks.h"

#include <gtest/gtest.h>

#include <cmath>
#include <new>
#include <string_view>
#include <string>

#include "avsi/core/error.h"
#include "avsi/core/json.h"

namespace avsi {
namespace {

// The first diagnostic of what `fn` throws (fails the test if it throws none).
template <class Fn>
Diagnostic first_problem(Fn&& fn) {
    try {
        fn();
    } catch (const InputError& e) {
        return e.first();
    }
    ADD_FAILURE() << "no InputError";
    return {};
}

TEST(Checks, RangeAndTimeChecksNameThePlaceAndTheLimits) {
    EXPECT_EQ(require_in_range(5.0, 0.0, 10.0, at("f.csv", 3, 2, "x")), 5.0);
    const Diagnostic d = first_problem([] { require_in_range(1e300, 0.0, 10.0, at("f.csv", 3, 2, "x")); });
    EXPECT_EQ(d.format(), "f.csv:3:2: error: x: expected a number in [0, 10], got 1e+300");
    EXPECT_NE(first_problem([] { require_time_s(std::nan(""), at("l.tsv", 1, 0, "end")); }).message.find("got nan"),
              std::string::npos);
    EXPECT_NO_THROW(require_time_s(max_time_s, at("l.tsv", 1, 0, "end")));
    EXPECT_THROW(require_time_s(max_time_s * 1.001, at("l.tsv", 1, 0, "end")), InputError);
    EXPECT_THROW(require_time_s(-1e-9, at("l.tsv", 1, 0, "end")), InputError);
    // One width of slack either side of [0, 1].
    EXPECT_NO_THROW(require_near_range(1.9, 0.0, 1.0, 1.0, at("t.csv", 2, 1, "p")));
    EXPECT_THROW(require_near_range(2.1, 0.0, 1.0, 1.0, at("t.csv", 2, 1, "p")), InputError);
}

TEST(Checks, DeclaredCountsAreBoundedByTheLimitAndTheBytesLeft) {
    EXPECT_EQ(require_declared_count(10, 4, 40, at("a.est", 3, 1, "NumFrames")), 10u);
    EXPECT_NE(first_problem([] { require_declared_count(11, 4, 40, at("a.est", 3, 1, "NumFrames")); })
                  .message.find("40 bytes hold at most 10"),
              std::string::npos);
    EXPECT_THROW(require_declared_count(1'000'000'000, 0, 1ull << 40, at("a.est", 3, 1, "NumFrames")), InputError);
    EXPECT_THROW(require_declared_count(-1, 1, 100, at("a.est", 3, 1, "NumFrames")), InputError);
}

TEST(Checks, LibraryExceptionsAreReRaisedNamingTheFile) {
    const Diagnostic alloc = first_problem([] { with_file_context("big.est", []() -> int { throw std::bad_alloc(); }); });
    EXPECT_EQ(alloc.path, "big.est");
    EXPECT_NE(alloc.message.find("out of memory"), std::string::npos);
    // A diagnostic without a file gets the file being read; others keep theirs.
    const Diagnostic unnamed = first_problem(
        [] { with_file_context("m.json", []() -> int { throw InputError(Diagnostic{"", 0, 0, "phone 2", "no entry", }); }); });
    EXPECT_EQ(unnamed.format(), "m.json: error: phone 2: no entry");
    const Diagnostic named = first_problem(
        [] { with_file_context("m.json", []() -> int { throw InputError("other.tsv", 4, 0, "end", "bad"); }); });
    EXPECT_EQ(named.path, "other.tsv");
}

TEST(Json, NestingBeyondTheLimitIsRefusedBeforeParsingWithLineAndColumn) {
    const std::string deep = "{\n  \"a\": " + std::string(100000, '[') + std::string(100000, ']') + "}";
    const Diagnostic d = first_problem([&] { parse_json(deep, "deep.json"); });
    // The object is level 1, so the 64th bracket (column 8 + 63) is level 65.
    EXPECT_EQ(d.format(), "deep.json:2:71: error: nesting: expected JSON nested at most 64 levels deep, got deeper");
    // Brackets inside strings do not count.
    EXPECT_NO_THROW(parse_json("{\"s\": \"" + std::string(1000, '[') + "\"}", "s.json"));
    EXPECT_NO_THROW(parse_json(std::string(max_json_depth, '[') + std::string(max_json_depth, ']'), "ok.json"));
}

TEST(Json, SyntaxAndNumberErrorsCarryFileLineAndColumn) {
    EXPECT_EQ(first_problem([] { parse_json("{\n  \"a\": 1,\n  \"b\": ]\n}", "s.json"); }).format().substr(0, 27),
              "s.json:3:8: error: invalid ");
    EXPECT_EQ(first_problem([] { parse_json("{\"a\": 1e999}", "n.json"); }).format(),
              "n.json:1:7: error: number: expected a number within the range of a double, got 1e999");
    const Diagnostic type = first_problem([] {
        const auto j = parse_json("[1]", "t.json");
        with_json_context("t.json", [&] { return j.value("a", 0); });
    });
    EXPECT_EQ(type.path, "t.json");
    EXPECT_EQ(type.message.find("[json.exception"), std::string::npos);
}

// A key of another type reads as the fallback instead of throwing
// nlohmann's type_error (a fuzzed manifest with "format": [...] crashed).
TEST(Json, StringFieldOfAnotherTypeGivesTheFallback) {
    const nlohmann::json j = nlohmann::json::parse(R"({"format": [1], "name": "x", "n": 3})");
    EXPECT_EQ(json_string(j, "name"), "x");
    EXPECT_EQ(json_string(j, "format"), "");
    EXPECT_EQ(json_string(j, "n", "?"), "?");
    EXPECT_EQ(json_string(j, "missing", "none"), "none");
    EXPECT_EQ(json_string(nlohmann::json::array(), "name", "none"), "none");
}

TEST(Hints, LongWordsGetNoDidYouMeanAndExcerptsEscapeControlCharacters) {
    EXPECT_EQ(closest_match("AAA", {"AA"}), "AA");
    EXPECT_EQ(closest_match(std::string(5'000'000, 'A'), {"AA"}), "");
    EXPECT_EQ(excerpt(std::string_view("s\0il", 4), 60), "s\\x00il");
    EXPECT_EQ(excerpt(std::string(100, 'K'), 4), "KKKK… (100 bytes)");
}

}  // namespace
}  // namespace avsi
