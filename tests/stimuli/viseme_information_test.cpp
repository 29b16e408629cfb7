// The objective viseme information (viseme_information.h): segments from
// per-frame measures, the cross-validated LDA and its T/RTI on synthetic
// segments with known answers. The same computation on a built set is held
// to the numpy reference by ctest -R VisemeInformation.MatchesNumpyReference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "avsi/core/phones.h"
#include "avsi/stimuli/viseme_information.h"

namespace avsi::stimuli {
namespace {

const std::vector<std::string> k_classes = {"bilabial", "lingual", "rounded", "open vowel"};

// 400 segments of 50 sentences (8 each), classes in turn; measures from `draw`.
template <class Draw>
std::vector<VisemeSegment> synthetic(const std::vector<std::string>& names, Draw draw) {
    std::vector<VisemeSegment> out;
    for (std::size_t i = 0; i < 400; ++i) {
        VisemeSegment s;
        s.condition = "model";
        s.sentence = "s" + std::to_string(100 + i / 8);
        s.phone = "X";
        s.viseme = names[i % names.size()];
        s.measures = draw(i % names.size());
        out.push_back(s);
    }
    return out;
}

std::array<double, viseme_measure_count> centre_of(std::size_t k) {
    std::array<double, viseme_measure_count> c{};
    for (std::size_t j = 0; j < c.size(); ++j) c[j] = 10.0 * std::sin(double(7 * k + 3 * j + 1));
    return c;
}

TEST(VisemeInformation, SeparableClassesGiveAccuracyOneAndRtiOne) {
    std::mt19937_64 rng(7);
    std::normal_distribution<double> noise(0.0, 0.01);
    const auto segments = synthetic(k_classes, [&](std::size_t k) {
        auto c = centre_of(k);
        for (auto& v : c) v += noise(rng);
        return c;
    });
    const auto r = viseme_information("model", segments);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->segments, 400u);
    EXPECT_EQ(r->sentences, 50u);
    EXPECT_EQ(r->accuracy, 1.0);
    EXPECT_NEAR(r->t.rti, 1.0, 1e-12);
    EXPECT_NEAR(r->t.t_corrected, r->t.h_x_corrected, 1e-12);
    EXPECT_DOUBLE_EQ(r->majority_class, 0.25);
    EXPECT_EQ(r->classes, (std::vector<std::string>{"bilabial", "lingual", "open vowel", "rounded"}));
    for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(r->confusion[i][i], 100.0);
}

TEST(VisemeInformation, UninformativeMeasuresGiveRtiAboutZero) {
    std::mt19937_64 rng(11);
    std::normal_distribution<double> noise(0.0, 1.0);
    const auto segments = synthetic(k_classes, [&](std::size_t) {
        std::array<double, viseme_measure_count> c{};
        for (auto& v : c) v = noise(rng);
        return c;
    });
    const auto r = viseme_information("model", segments);
    ASSERT_TRUE(r);
    EXPECT_LT(r->accuracy, r->majority_class + 0.1);
    EXPECT_LT(std::fabs(r->t.rti), 0.05);
}

// Renaming the classes (which reorders them) changes nothing but the names.
TEST(VisemeInformation, InvariantToRelabelling) {
    std::mt19937_64 rng(3);
    std::normal_distribution<double> noise(0.0, 4.0);
    std::vector<std::array<double, viseme_measure_count>> drawn;
    const auto a = synthetic(k_classes, [&](std::size_t k) {
        auto c = centre_of(k);
        for (auto& v : c) v += noise(rng);
        drawn.push_back(c);
        return c;
    });
    std::size_t i = 0;
    const std::vector<std::string> renamed = {"zeta", "alpha", "mu", "beta"};
    const auto b = synthetic(renamed, [&](std::size_t) { return drawn[i++]; });
    const auto ra = viseme_information("model", a), rb = viseme_information("model", b);
    ASSERT_TRUE(ra && rb);
    EXPECT_GT(ra->accuracy, ra->majority_class + 0.1);  // informative but not separable
    EXPECT_LT(ra->accuracy, 1.0);
    EXPECT_DOUBLE_EQ(ra->accuracy, rb->accuracy);
    EXPECT_NEAR(ra->t.t_corrected, rb->t.t_corrected, 1e-12);
    EXPECT_NEAR(ra->t.rti, rb->t.rti, 1e-12);
    for (std::size_t s = 0; s < a.size(); ++s) {
        const std::size_t k = std::size_t(std::find(k_classes.begin(), k_classes.end(), ra->predicted[s]) -
                                          k_classes.begin());
        EXPECT_EQ(rb->predicted[s], renamed[k]) << s;
    }
}

// Folds by sentence: the sorted sentence ids, the i-th in fold i mod 5.
TEST(VisemeInformation, FoldsBySortedSentence) {
    const auto segments = synthetic(k_classes, [](std::size_t k) { return centre_of(k); });
    const auto r = viseme_information("model", segments);
    ASSERT_TRUE(r);
    for (std::size_t i = 0; i < segments.size(); ++i) EXPECT_EQ(r->fold[i], (i / 8) % 5) << i;
}

TEST(VisemeInformation, NeedsTwoSentences) {
    auto segments = synthetic(k_classes, [](std::size_t k) { return centre_of(k); });
    for (auto& s : segments) s.sentence = "only";
    EXPECT_FALSE(viseme_information("model", segments));
}

// A segment is the mean of its frames (k / fps in [start, end)), or the frame
// nearest its centre; silence is no segment; the class is core's VisemeClass.
TEST(VisemeInformation, SegmentsAreFrameMeansLabelledByVisemeClass) {
    std::vector<synth::ArticulationMeasures> frames(10);
    for (std::size_t k = 0; k < frames.size(); ++k) {
        frames[k].aperture_mid_mm = double(k);
        frames[k].lip_to_incisors_mm = 100.0 + double(k);
    }
    // 10 fps: P covers frames 1-3, UW lies between frames 5 and 6 (nearest 6).
    const PhoneSequence phones = {{"sil", 0.0, 0.1}, {"P", 0.1, 0.4}, {"AA", 0.4, 0.52}, {"UW", 0.56, 0.59}};
    const auto s = viseme_segments("rule", "s1", phones, frames, 10.0);
    ASSERT_EQ(s.size(), 3u);
    EXPECT_EQ(s[0].phone, "P");
    EXPECT_EQ(s[0].viseme, "bilabial");
    EXPECT_DOUBLE_EQ(s[0].measures[0], 2.0);  // mean of frames 1, 2, 3
    EXPECT_DOUBLE_EQ(s[0].measures[5], 102.0);
    EXPECT_EQ(s[1].viseme, "open vowel");
    EXPECT_DOUBLE_EQ(s[1].measures[0], 4.5);  // frames 4 and 5
    EXPECT_EQ(s[2].viseme, "rounded");
    EXPECT_DOUBLE_EQ(s[2].measures[0], 6.0);  // no frame inside: the nearest to 0.575 s
}

// Every Swedish phone gets a class (the language's features); /yː/ is rounded.
TEST(VisemeInformation, SwedishPhonesHaveVisemeClasses) {
    const auto& inventory = PhoneInventory::builtin();
    PhoneSequence phones;
    double t = 0.0;
    for (const auto& symbol : inventory.language_phones("sv")) {
        phones.push_back({symbol, t, t + 0.1});
        t += 0.1;
    }
    const std::vector<synth::ArticulationMeasures> frames(std::size_t(t * 30.0) + 1);
    const auto s = viseme_segments("rule", "sv001", phones, frames, 30.0);
    EXPECT_EQ(s.size() + 1, phones.size());  // all but sil
    std::set<std::string> classes;
    for (const auto& seg : s) {
        classes.insert(seg.viseme);
        if (seg.phone == "YY") {
            EXPECT_EQ(seg.viseme, "rounded");
        }
    }
    for (const char* c : {"bilabial", "labiodental", "rounded", "open vowel", "spread vowel", "lingual"})
        EXPECT_TRUE(classes.count(c)) << c;
}

}  // namespace
}  // namespace avsi::stimuli
