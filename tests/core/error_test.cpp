#include "avsi/core/error.h"

#include <gtest/gtest.h>

namespace avsi {
namespace {

TEST(Diagnostic, FormatsCompilerStyle) {
    Diagnostic d{"protocols/study.toml", 17, 9, "vocoder.bands",
                 "expected an integer in [1, 32], got \"three\""};
    EXPECT_EQ(d.format(),
              "protocols/study.toml:17:9: error: vocoder.bands: expected an integer in [1, 32], got "
              "\"three\"");
}

TEST(Diagnostic, OmitsMissingParts) {
    EXPECT_EQ((Diagnostic{"a.lab", 3, 0, "", "bad"}.format()), "a.lab:3: error: bad");
    EXPECT_EQ((Diagnostic{"a.wav", 0, 0, "", "no such file"}.format()), "a.wav: error: no such file");
}

TEST(InputError, CarriesAllDiagnosticsAndJoinsThemInWhat) {
    DiagnosticList list;
    list.add("f.toml", 1, 1, "a", "expected x, got y");
    list.add("f.toml", 2, 5, "b", "expected z, got w");
    try {
        list.throw_if_any();
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        ASSERT_EQ(e.diagnostics().size(), 2u);
        EXPECT_EQ(e.first().line, 1);
        EXPECT_STREQ(e.what(),
                     "f.toml:1:1: error: a: expected x, got y\nf.toml:2:5: error: b: expected z, got w");
    }
}

TEST(DiagnosticList, EmptyDoesNotThrow) {
    DiagnosticList list;
    EXPECT_NO_THROW(list.throw_if_any());
}

TEST(EditDistance, CountsTranspositionAsOne) {
    EXPECT_EQ(edit_distance("bands", "bands"), 0u);
    EXPECT_EQ(edit_distance("bands", "bnads"), 1u);
    EXPECT_EQ(edit_distance("band", "bands"), 1u);
    EXPECT_EQ(edit_distance("", "abc"), 3u);
    EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
}

TEST(ClosestMatch, SuggestsOnlyPlausibleTypos) {
    const std::vector<std::string> keys{"bands", "low_hz", "high_hz", "carrier"};
    EXPECT_EQ(closest_match("band", keys), "bands");
    EXPECT_EQ(closest_match("carier", keys), "carrier");
    EXPECT_EQ(closest_match("completely_different", keys), "");
}

}  // namespace
}  // namespace avsi
