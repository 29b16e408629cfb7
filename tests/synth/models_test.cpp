// The control models: equations at hand-computed points of 3-segment
// utterances, the bounded Cohen-Massaro sum against the full sum, Öhman's
// C¹ continuity, rule interpolation, MPEG-4 α, frame-rate agreement, model
// files and their errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "avsi/core/error.h"
#include "avsi/core/rng.h"
#include "avsi/synth/cohen_massaro.h"
#include "avsi/synth/mpeg4_cohen_massaro.h"
#include "avsi/synth/ohman.h"
#include "avsi/synth/rule_model.h"
#include "avsi/synth/synthesis.h"
#include "test_util.h"

namespace avsi::synth {
namespace {

const std::filesystem::path models_dir = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models";

CohenMassaroPhone cm_phone(double target, double alpha, double theta, double phi, double c) {
    CohenMassaroPhone p;
    p.c = c;
    for (auto& q : p.params) q = {target, alpha, theta, phi};
    return p;
}

// sil [0, 0.1], AA [0.1, 0.3], P [0.3, 0.4]: centres 0.05, 0.2, 0.35.
PhoneSequence three_segments() { return test::make_phones({{"sil", 0.1}, {"AA", 0.2}, {"P", 0.1}}); }

TEST(CohenMassaro, HandComputedPointsOfThreeSegments) {
    CohenMassaroModel model({{"sil", cm_phone(0.0, 1.0, 10.0, 10.0, 1.0)},
                             {"AA", cm_phone(1.0, 1.0, 10.0, 10.0, 1.0)},
                             {"P", cm_phone(-0.5, 2.0, 20.0, 20.0, 1.0)}});
    const double times[] = {0.2, 0.3};
    std::vector<Frame> out;
    model.evaluate(three_segments(), times, out);
    // t = 0.2: D = exp(−1.5), 1, 2·exp(−3): z = (1 − 0.5·2e^−3) / (e^−1.5 + 1 + 2e^−3).
    EXPECT_NEAR(out[0][0], 0.7183865160720465, 1e-12);
    // t = 0.3: D = e^−2.5, e^−1, 2e^−1: z = (e^−1 − e^−1) / … = 0.
    EXPECT_NEAR(out[1][0], 0.0, 1e-12);
    for (std::size_t p = 1; p < param_count; ++p) EXPECT_EQ(out[0][p], out[0][0]);
}

TEST(CohenMassaro, DominanceFollowsEquation7) {
    const CmSegment s{0.35, -0.5, 2.0, 20.0, 5.0, 2.0};
    EXPECT_NEAR(dominance(s, 0.3), 2.0 * std::exp(-20.0 * 0.05 * 0.05), 1e-15);  // before τ: θ
    EXPECT_NEAR(dominance(s, 0.45), 2.0 * std::exp(-5.0 * 0.1 * 0.1), 1e-15);    // after τ: φ
    EXPECT_EQ(dominance(s, 0.35), 2.0);
    EXPECT_NEAR(dominance(s, 0.3), 1.902458849001428, 1e-12);
}

TEST(CohenMassaro, BoundedSumWithin1e9OfFullSum) {
    for (std::uint64_t seed = 1; seed <= 40; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        const std::size_t n = 1 + rng.uniform_int(seed % 4 == 0 ? 8 : 300);
        std::vector<CmSegment> segs;
        double t = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            const double d = rng.uniform(0.02, seed % 5 == 0 ? 1.5 : 0.3);
            const double c = seed % 3 == 0 ? 1.0 : rng.uniform(0.5, 2.5);
            segs.push_back({t + d / 2, rng.uniform(-1.0, 1.0), rng.uniform(0.02, 3.0), rng.uniform(3.0, 120.0),
                            rng.uniform(3.0, 120.0), c});
            t += d;
        }
        const double fps = seed % 2 ? 60.0 : 90.0;
        std::vector<double> times(frame_count(t, fps));
        for (std::size_t k = 0; k < times.size(); ++k) times[k] = double(k) / fps;
        std::vector<double> full(times.size()), bounded(times.size());
        cohen_massaro_full(segs, times, full);
        cohen_massaro_bounded(segs, times, bounded);
        double worst = 0.0;
        for (std::size_t k = 0; k < times.size(); ++k) worst = std::max(worst, std::abs(full[k] - bounded[k]));
        EXPECT_LE(worst, 1e-9);
    }
}

TEST(CohenMassaro, BoundedSumSkipsFarSegments) {
    // The bound is not vacuous: a far, weak segment is dropped (its exact
    // effect is below the tolerance but not zero).
    const std::vector<CmSegment> segs{{0.1, 0.0, 1.0, 50.0, 50.0, 1.0}, {3.0, 1.0, 1.0, 50.0, 50.0, 1.0}};
    const double times[] = {0.1};
    double full[1], bounded[1];
    cohen_massaro_full(segs, times, full);
    cohen_massaro_bounded(segs, times, bounded);
    EXPECT_GT(full[0], 0.0);
    EXPECT_EQ(bounded[0], 0.0);
    EXPECT_LE(full[0], cm_default_tolerance);
}

// An utterance's segments for every parameter: per segment one centre and one
// c (as the models make them, unless `shared` is false), per parameter random
// T, α, θ, φ. Returns the utterance end.
double random_segments_all(Rng& rng, std::size_t n, bool shared, bool unit_c,
                           std::array<std::vector<CmSegment>, param_count>& all) {
    double t = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double d = rng.uniform(0.02, 0.3);
        const double c = unit_c ? 1.0 : rng.uniform(0.5, 2.5);
        for (std::size_t p = 0; p < param_count; ++p) {
            const double tau = t + d / 2 + (shared ? 0.0 : rng.uniform(-0.01, 0.01));
            all[p].push_back({tau, rng.uniform(-1.0, 1.0), rng.uniform(0.02, 3.0), rng.uniform(3.0, 120.0),
                              rng.uniform(3.0, 120.0), shared ? c : rng.uniform(0.5, 2.5)});
        }
        t += d;
    }
    return t;
}

// Worst |bounded_all − full| over every frame and parameter.
double worst_all_vs_full(const std::array<std::vector<CmSegment>, param_count>& all, std::span<const double> times) {
    std::vector<Frame> bounded;
    cohen_massaro_bounded_all(all, times, bounded);
    EXPECT_EQ(bounded.size(), times.size());
    double worst = 0.0;
    std::vector<double> full(times.size());
    for (std::size_t p = 0; p < param_count; ++p) {
        cohen_massaro_full(all[p], times, full);
        for (std::size_t k = 0; k < times.size(); ++k) worst = std::max(worst, std::abs(full[k] - bounded[k][p]));
    }
    return worst;
}

TEST(CohenMassaro, BoundedSumOfAllParametersWithin1e9OfFullSum) {
    for (std::uint64_t seed = 1; seed <= 16; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        std::array<std::vector<CmSegment>, param_count> all;
        // seed % 4 == 0: centres and c differ between parameters (the
        // parameter-by-parameter path); seed % 3 == 0: c = 1 throughout.
        const double end_s = random_segments_all(rng, 1 + rng.uniform_int(200), seed % 4 != 0, seed % 3 == 0, all);
        std::vector<double> times(frame_count(end_s, 60.0));
        for (std::size_t k = 0; k < times.size(); ++k) times[k] = double(k) / 60.0;
        if (seed % 2 == 0) {  // irregular times
            for (auto& t : times) t = rng.uniform(0.0, end_s);
            std::sort(times.begin(), times.end());
        }
        EXPECT_LE(worst_all_vs_full(all, times), 1e-9);
    }
}

TEST(CohenMassaro, BoundedSumWithExtremeRatesStaysWithin1e9) {
    // θ, φ ~ 1e5/s: the owner's dominance at its cell edge is ~e^−5000, below
    // the range of doubles, so these cells are summed in the log domain.
    Rng rng(7);
    std::array<std::vector<CmSegment>, param_count> all;
    random_segments_all(rng, 30, true, true, all);
    for (auto& segs : all)
        for (std::size_t i = 0; i < segs.size(); ++i)
            if (i % 2 == 0) segs[i].theta_per_s = segs[i].phi_per_s = rng.uniform(5e4, 1e5);
    std::vector<double> times(500);
    for (std::size_t k = 0; k < times.size(); ++k) times[k] = all[0].back().tau_s * double(k) / 499.0;
    EXPECT_LE(worst_all_vs_full(all, times), 1e-9);
    std::vector<double> full(times.size()), bounded(times.size());
    cohen_massaro_full(all[3], times, full);
    cohen_massaro_bounded(all[3], times, bounded);
    for (std::size_t k = 0; k < times.size(); ++k) {
        ASSERT_TRUE(std::isfinite(bounded[k])) << k;
        EXPECT_NEAR(bounded[k], full[k], 1e-9) << k;
    }
}

// Segments as a model makes them: per segment one of `keys` phone keys, each
// key with its own c (c = 1 for the first `unit_keys` keys) and per parameter
// T, α, θ, φ; rates drawn from [rate_lo, rate_hi]. Returns the utterance end.
double keyed_segments_all(Rng& rng, std::size_t n, std::size_t keys, std::size_t unit_keys, double rate_lo,
                          double rate_hi, std::array<std::vector<CmSegment>, param_count>& all) {
    std::vector<std::array<CmSegment, param_count>> table(keys);
    for (std::size_t k = 0; k < keys; ++k) {
        const double c = k < unit_keys ? 1.0 : rng.uniform(0.5, 2.5);
        for (auto& s : table[k])
            s = {0.0, rng.uniform(-1.0, 1.0), rng.uniform(0.02, 3.0), rng.uniform(rate_lo, rate_hi),
                 rng.uniform(rate_lo, rate_hi), c};
    }
    double t = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double d = rng.uniform(0.03, 0.3);
        const std::size_t k = rng.uniform_int(keys);
        for (std::size_t p = 0; p < param_count; ++p) {
            CmSegment s = table[k][p];
            s.tau_s = t + d / 2;
            all[p].push_back(s);
        }
        t += d;
    }
    return t;
}

TEST(CohenMassaro, UnitExponentRecursionsWithin1e9OfFullSum) {
    // On uniform frames the c = 1 segments are summed whole by recursions
    // (cohen_massaro.cpp), the others by the bound: all c = 1, a mix, slow
    // rates with tails over the whole utterance, and fast rates whose sums
    // decay into the subnormal range (flushed) within a few frames.
    struct Case {
        std::size_t keys, unit_keys;
        double rate_lo, rate_hi, fps;
    };
    const Case cases[] = {{30, 30, 3.0, 60.0, 60.0},  {30, 15, 3.0, 60.0, 60.0},  {12, 12, 1.0, 5.0, 25.0},
                          {40, 20, 1.0, 10.0, 90.0},   {20, 20, 2000.0, 6000.0, 60.0}, {20, 10, 500.0, 6000.0, 60.0},
                          {5, 5, 20.0, 20.0, 60.0}};
    std::uint64_t seed = 100;
    for (const Case& c : cases) {
        SCOPED_TRACE("keys " + std::to_string(c.keys) + ", c = 1 for " + std::to_string(c.unit_keys) + ", rates " +
                     std::to_string(c.rate_lo) + ".." + std::to_string(c.rate_hi));
        Rng rng(++seed);
        std::array<std::vector<CmSegment>, param_count> all;
        const double end_s = keyed_segments_all(rng, 150, c.keys, c.unit_keys, c.rate_lo, c.rate_hi, all);
        std::vector<double> times(frame_count(end_s, c.fps));
        for (std::size_t k = 0; k < times.size(); ++k) times[k] = double(k) / c.fps;
        EXPECT_LE(worst_all_vs_full(all, times), 1e-9);
        // One parameter alone (the single-parameter path).
        std::vector<double> full(times.size()), bounded(times.size());
        cohen_massaro_full(all[4], times, full);
        cohen_massaro_bounded(all[4], times, bounded);
        double worst = 0.0;
        for (std::size_t k = 0; k < times.size(); ++k) worst = std::max(worst, std::abs(full[k] - bounded[k]));
        EXPECT_LE(worst, 1e-9);
    }
    // The flush-to-zero mode of the recursions is the caller's again after.
    volatile double tiny = 1e-300;
    const double subnormal = tiny * 1e-10;
    EXPECT_GT(subnormal, 0.0);
}

TEST(Ohman, HandComputedPointsOfThreeSegments) {
    // AA [0, 0.2], P [0.2, 0.3], IY [0.3, 0.5]: centres 0.1, 0.25, 0.4.
    Frame aa{}, iy{};
    aa.fill(0.8);
    iy.fill(0.2);
    OhmanConsonant p{};
    for (auto& q : p) q = {-0.4, 0.75};
    OhmanModel model({{"AA", aa}, {"IY", iy}}, {{"P", p}});
    const auto phones = test::make_phones({{"AA", 0.2}, {"P", 0.1}, {"IY", 0.2}});
    const double times[] = {0.25, 0.175, 0.1, 0.45};
    std::vector<Frame> out;
    model.evaluate(phones, times, out);
    // t = 0.25: v = (0.8 + 0.2)/2 = 0.5, k = 1: z = 0.5 + 0.75·(−0.4 − 0.5) = −0.175.
    EXPECT_NEAR(out[0][0], -0.175, 1e-12);
    // t = 0.175: x = 0.25, s = 0.15625, v = 0.8·0.84375 + 0.2·0.15625 = 0.70625;
    // k = s(0.5) = 0.5: z = v + 0.75·0.5·(−0.4 − v) = 0.2915625.
    EXPECT_NEAR(out[1][0], 0.70625 + 0.375 * (-0.4 - 0.70625), 1e-12);
    EXPECT_NEAR(out[2][0], 0.8, 1e-12);   // a vowel centre: its own target
    EXPECT_NEAR(out[3][0], 0.2, 1e-12);   // after the last vowel centre: held
}

TEST(Ohman, EdgesNoVowelAndOneVowel) {
    Frame aa{};
    aa.fill(0.8);
    OhmanConsonant p{};
    for (auto& q : p) q = {-0.4, 0.5};
    OhmanModel model({{"AA", aa}}, {{"P", p}, {"M", p}});
    std::vector<Frame> out;
    // No vowel: the vowel track is neutral; a consonant edge segment keeps k = 1.
    const double t0[] = {0.0, 0.05};
    model.evaluate(test::make_phones({{"P", 0.1}, {"M", 0.1}}), t0, out);
    EXPECT_NEAR(out[0][0], 0.5 * -0.4, 1e-12);
    EXPECT_NEAR(out[1][0], 0.5 * -0.4, 1e-12);
    // One vowel: constant vowel track.
    std::vector<Frame> track;
    const double t1[] = {0.0, 0.15, 0.3};
    model.vowel_track(test::make_phones({{"P", 0.1}, {"AA", 0.1}, {"M", 0.1}}), t1, track);
    for (const auto& f : track) EXPECT_EQ(f[0], 0.8);
}

TEST(Ohman, DefaultModelIsC1AtEverySegmentCentre) {
    const auto model = load_model(models_dir / "ohman.json");
    const std::vector<std::string> symbols{"sil", "AA", "P", "R", "IY", "S", "T", "UW", "W", "M", "EH", "F", "sil"};
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        std::vector<std::pair<std::string, double>> items;
        for (int i = 0; i < 12; ++i) items.emplace_back(symbols[rng.uniform_int(symbols.size())], rng.uniform(0.04, 0.25));
        const auto phones = test::make_phones(items);
        const double h = 1e-7;
        for (const auto& ph : phones) {
            const double c = ph.centre_s();
            const double times[] = {c - h, c, c + h};
            std::vector<Frame> z;
            model->evaluate(phones, times, z);
            for (std::size_t p = 0; p < param_count; ++p) {
                EXPECT_NEAR(z[0][p], z[1][p], 1e-4);
                const double left = (z[1][p] - z[0][p]) / h, right = (z[2][p] - z[1][p]) / h;
                EXPECT_NEAR(left, right, 2e-3) << ph.symbol << " at " << c << " param " << p;
            }
        }
    }
}

TEST(Ohman, ContinuousDerivativeDetectsAKink) {
    // The numerical check can fail: a piecewise-linear rule track (σ = 0) has
    // a kink at a specified centre.
    RuleModel::Table table;
    RuleTarget t{};
    t[0] = 0.9;
    table["AA"] = t;
    RuleModel model(table, 0.0);
    const auto phones = test::make_phones({{"AA", 0.2}});
    const double h = 1e-7, c = 0.1;
    const double times[] = {c - h, c, c + h};
    std::vector<Frame> z;
    model.evaluate(phones, times, z);
    EXPECT_GT(std::abs((z[1][0] - z[0][0]) / h - (z[2][0] - z[1][0]) / h), 1.0);
}

TEST(Rule, InterpolatesUnspecifiedTargets) {
    // sil [0, 0.1] (all 0), HH [0.1, 0.2] (unspecified), AA [0.2, 0.4] (jaw 0.9).
    RuleModel::Table table;
    RuleTarget sil{}, hh{}, aa{};
    for (auto& v : sil) v = 0.0;
    aa[index(Param::JawRotation)] = 0.9;
    table["sil"] = sil;
    table["HH"] = hh;
    table["AA"] = aa;
    const auto phones = test::make_phones({{"sil", 0.1}, {"HH", 0.1}, {"AA", 0.2}});
    RuleModel sharp(table, 0.0);
    const double times[] = {0.15, 0.3, 0.35, 0.175};
    std::vector<Frame> lin;
    sharp.evaluate(phones, times, lin);
    const std::size_t jaw = index(Param::JawRotation);
    EXPECT_NEAR(lin[0][jaw], 0.9 * 0.1 / 0.25, 1e-12);  // HH centre: between sil (0.05) and AA (0.3)
    EXPECT_NEAR(lin[1][jaw], 0.9, 1e-12);              // AA centre
    EXPECT_NEAR(lin[2][jaw], 0.45, 1e-12);             // halfway to the neutral end at 0.4
    // Smoothed: far (> 10σ) from every knot the Gaussian leaves a line unchanged.
    RuleModel smooth(table, 0.005);
    std::vector<Frame> sm;
    smooth.evaluate(phones, times, sm);
    EXPECT_NEAR(sm[3][jaw], 0.9 * 0.125 / 0.25, 1e-12);
    EXPECT_LT(sm[1][jaw], 0.9);  // the corner at the AA centre is rounded off
}

TEST(Rule, ClosedFormSmoothingMatchesNumericalConvolution) {
    RuleModel::Table table;
    RuleTarget sil{}, aa{}, p{};
    for (auto& v : sil) v = 0.0;
    aa[0] = 0.9;
    p[0] = 0.1;
    table["sil"] = sil;
    table["AA"] = aa;
    table["P"] = p;
    const auto phones = test::make_phones({{"sil", 0.1}, {"AA", 0.12}, {"P", 0.08}, {"AA", 0.1}, {"sil", 0.1}});
    const double sigma = 0.02;
    RuleModel sharp(table, 0.0), smooth(table, sigma);
    for (double t : {0.1, 0.16, 0.2, 0.26, 0.31}) {
        // Simpson's rule over ±10σ of the linear track times the Gaussian.
        const int n = 4000;
        const double a = t - 10 * sigma, step = 20 * sigma / n;
        std::vector<double> ts(n + 1);
        for (int i = 0; i <= n; ++i) ts[i] = a + i * step;
        std::vector<Frame> lin;
        sharp.interpolated(phones, ts, lin);
        double sum = 0.0;
        for (int i = 0; i <= n; ++i) {
            const double u = (ts[i] - t) / sigma;
            const double g = std::exp(-0.5 * u * u) / (sigma * std::sqrt(2 * std::numbers::pi));
            sum += (i == 0 || i == n ? 1 : i % 2 ? 4 : 2) * g * lin[i][0];
        }
        sum *= step / 3;
        std::vector<Frame> closed;
        const double one[] = {t};
        smooth.evaluate(phones, one, closed);
        EXPECT_NEAR(closed[0][0], sum, 1e-9) << "t = " << t;
    }
}

TEST(Mpeg4CohenMassaro, AlphaEqualsNormalisedEllipseArea) {
    const auto model = load_model(models_dir / "mpeg4-cohen-massaro.json");
    const auto* m4 = dynamic_cast<const Mpeg4CohenMassaroModel*>(model.get());
    ASSERT_NE(m4, nullptr);
    const auto& set = m4->viseme_set();
    ASSERT_EQ(set.visemes.size(), 15u);  // 0 none + 14
    double largest = 0.0;
    for (const auto& v : set.visemes) largest = std::max(largest, std::numbers::pi * v.width_mm * v.height_mm);
    for (std::size_t i = 0; i < set.visemes.size(); ++i)
        EXPECT_NEAR(m4->alphas()[i], std::numbers::pi * set.visemes[i].width_mm * set.visemes[i].height_mm / largest,
                    1e-15);
    // By hand from protocols/visemes/mpeg4_14.json: p_b_m 50 × 12.2 mm, e 61.2 × 24.87 mm (the largest).
    EXPECT_NEAR(m4->alphas()[1], 50.0 * 12.2 / (61.2 * 24.87), 1e-12);
    EXPECT_EQ(m4->alphas()[11], 1.0);
}

TEST(Mpeg4CohenMassaro, SegmentsFollowEquations5And6) {
    VisemeSet set = load_viseme_set(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "visemes" / "mpeg4_14.json");
    Mpeg4CmSettings s;
    s.theta_anticipatory_per_s = 12.0;
    s.theta_carryover_per_s = 30.0;
    s.t0_s = 0.01;
    s.t0_s_by_viseme["p_b_m"] = -0.02;
    Mpeg4CohenMassaroModel model(set, "x.json", s);
    const auto segs = model.segments(three_segments(), Param::JawRotation);
    ASSERT_EQ(segs.size(), 3u);
    EXPECT_NEAR(segs[1].tau_s, 0.2 + 0.01, 1e-15);   // AA: centre + t0
    EXPECT_NEAR(segs[2].tau_s, 0.35 - 0.02, 1e-15);  // P: per-viseme override
    EXPECT_EQ(segs[1].theta_per_s, 12.0);
    EXPECT_EQ(segs[1].phi_per_s, 30.0);
    EXPECT_EQ(segs[1].c, 1.0);
    EXPECT_EQ(segs[1].target, set.viseme_of("AA").targets[index(Param::JawRotation)]);
    // D before the peak uses θ← (eq. 5, τ >= 0), after it θ→.
    EXPECT_NEAR(dominance(segs[1], 0.11), segs[1].alpha * std::exp(-12.0 * 0.1), 1e-15);
    EXPECT_NEAR(dominance(segs[1], 0.31), segs[1].alpha * std::exp(-30.0 * 0.1), 1e-15);
}

TEST(VisemeSets, BothSetsMapEveryPhoneOnce) {
    for (const char* name : {"mpeg4_14.json", "avsi_17.json"}) {
        SCOPED_TRACE(name);
        const auto set = load_viseme_set(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "visemes" / name);
        EXPECT_EQ(set.phone_to_viseme.size(), PhoneInventory::builtin().language_phones("en").size());
    }
    EXPECT_EQ(load_viseme_set(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "visemes" / "avsi_17.json").visemes.size(),
              17u);
}

TEST(DefaultModels, AgreeAtSharedTimesAcrossFrameRates) {
    const auto phones = test::make_phones({{"sil", 0.15}, {"K", 0.07}, {"AH", 0.09}, {"M", 0.08}, {"HH", 0.06},
                                           {"IY", 0.12}, {"R", 0.07}, {"JH", 0.09}, {"AA", 0.16}, {"N", 0.09},
                                           {"sil", 0.153}});
    for (const char* file : {"rule.json", "cohen-massaro.json", "mpeg4-cohen-massaro.json", "ohman.json"}) {
        SCOPED_TRACE(file);
        const auto model = load_model(models_dir / file);
        const double end = phones.back().end_s;
        const Trajectory a = model->synthesize(phones, 25.0), b = model->synthesize(phones, 60.0),
                         c = model->synthesize(phones, 90.0);
        EXPECT_EQ(a.size(), frame_count(end, 25.0));
        EXPECT_EQ(b.size(), frame_count(end, 60.0));
        EXPECT_EQ(c.size(), frame_count(end, 90.0));
        EXPECT_EQ(a.size(), 29u);   // 1.133 s · 25 = 28.3 → 29
        EXPECT_EQ(c.size(), 102u);  // 1.133 s · 90 = 101.97 → 102
        // Shared times: multiples of 0.2 s (5, 12 and 18 frames).
        for (std::size_t m = 0; 5 * m < a.size(); ++m) {
            ASSERT_EQ(a.time_s(5 * m), b.time_s(12 * m));
            ASSERT_EQ(a.time_s(5 * m), c.time_s(18 * m));
            for (std::size_t p = 0; p < param_count; ++p) {
                EXPECT_NEAR(a.frames[5 * m][p], b.frames[12 * m][p], 1e-9);
                EXPECT_NEAR(a.frames[5 * m][p], c.frames[18 * m][p], 1e-9);
            }
        }
    }
}

TEST(DefaultModels, ArePhoneticallySensible) {
    // sil M AA F UW IY sil: lips close for /m/, open jaw for /aa/, lower lip
    // tucked for /f/, rounded for /uw/, spread for /iy/.
    // The 200 ms vowels are stressed: the trained defaults (protocols/models)
    // learn reduced unstressed vowels from the reference speaker, as it has them.
    auto phones = test::make_phones(
        {{"sil", 0.2}, {"M", 0.1}, {"AA", 0.2}, {"F", 0.1}, {"UW", 0.2}, {"W", 0.08}, {"IY", 0.2}, {"sil", 0.2}});
    for (std::size_t i : {2, 4, 6}) phones[i].stressed = true;
    for (const char* file : {"rule.json", "cohen-massaro.json", "mpeg4-cohen-massaro.json", "ohman.json"}) {
        SCOPED_TRACE(file);
        const auto model = load_model(models_dir / file);
        std::vector<double> centres;
        for (const auto& p : phones) centres.push_back(p.centre_s());
        std::vector<Frame> z;
        model->evaluate(phones, centres, z);
        auto v = [&](std::size_t seg, Param p) { return z[seg][index(p)]; };
        EXPECT_LT(v(1, Param::LowerLipDepression), 0.0);        // M: lower lip raised
        EXPECT_LT(v(1, Param::JawRotation), v(2, Param::JawRotation) - 0.15);
        EXPECT_GT(v(2, Param::JawRotation), 0.3);                // AA: open
        EXPECT_GT(v(3, Param::LowerLipRetraction), 0.3);         // F: lower lip under the teeth
        EXPECT_GT(v(4, Param::LipRounding), 0.5);                // UW: rounded
        EXPECT_LT(v(4, Param::UpperLipRetraction), -0.2);        // … and protruded,
        EXPECT_LT(v(4, Param::UpperLipRetraction), v(6, Param::UpperLipRetraction) - 0.2);  // more than IY
        // IY: spread, against UW (after /w/ its absolute values carry some rounding over).
        EXPECT_GT(v(6, Param::MouthCornerStretchLeft), v(4, Param::MouthCornerStretchLeft) + 0.2);
        EXPECT_LT(v(6, Param::LipRounding), v(4, Param::LipRounding) - 0.4);
        EXPECT_NEAR(v(7, Param::JawRotation), 0.0, 0.15);        // pause: near rest
    }
}

TEST(ModelFiles, SaveAndLoadRoundTrip) {
    const auto dir = test::temp_dir("roundtrip");
    const auto phones = test::make_phones({{"sil", 0.1}, {"B", 0.08}, {"AO", 0.15}, {"sil", 0.1}});
    for (const char* file : {"rule.json", "cohen-massaro.json", "mpeg4-cohen-massaro.json", "ohman.json"}) {
        SCOPED_TRACE(file);
        const auto model = load_model(models_dir / file);
        // MPEG-4 files refer to their viseme set relative to the model file.
        std::filesystem::create_directories(dir / "models");
        std::filesystem::create_directories(dir / "visemes");
        std::filesystem::copy_file(models_dir.parent_path() / "visemes" / "mpeg4_14.json",
                                   dir / "visemes" / "mpeg4_14.json",
                                   std::filesystem::copy_options::overwrite_existing);
        // A trained MPEG-4 model keeps its viseme targets beside it (training.h).
        if (std::filesystem::exists(models_dir / "mpeg4-cohen-massaro.visemes.json"))
            std::filesystem::copy_file(models_dir / "mpeg4-cohen-massaro.visemes.json",
                                       dir / "models" / "mpeg4-cohen-massaro.visemes.json",
                                       std::filesystem::copy_options::overwrite_existing);
        const auto out = dir / "models" / file;
        save_model(*model, out);
        const auto back = load_model(out);
        EXPECT_EQ(back->kind(), model->kind());
        EXPECT_EQ(back->provenance().notes, model->provenance().notes);
        const Trajectory a = model->synthesize(phones, 60.0), b = back->synthesize(phones, 60.0);
        ASSERT_EQ(a.size(), b.size());
        for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a.frames[k], b.frames[k]);
    }
}

TEST(ModelFiles, StressSpecificKeysTakePrecedence) {
    CohenMassaroModel model({{"AA", cm_phone(0.5, 1, 10, 10, 1)}, {"AA1", cm_phone(0.9, 1, 10, 10, 1)}});
    PhoneSequence phones{{"AA", 0.0, 0.2, true}};
    EXPECT_NEAR(model.synthesize(phones, 60.0).frames[3][0], 0.9, 1e-12);
    phones[0].stressed = false;
    EXPECT_NEAR(model.synthesize(phones, 60.0).frames[3][0], 0.5, 1e-12);
}

std::string load_error(const std::string& json) {
    const auto dir = test::temp_dir("bad");
    test::write_file(dir / "m.json", json);
    try {
        load_model(dir / "m.json");
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

TEST(ModelFiles, BadFilesNameFileAndField) {
    const std::string prov = R"("provenance": {"method": "hand-set"})";
    auto e = load_error(R"({"kind": "cohen-masaro", "version": 1, )" + prov + "}");
    EXPECT_NE(e.find("m.json: error: /kind: "), std::string::npos) << e;
    EXPECT_NE(e.find("did you mean \"cohen-massaro\""), std::string::npos) << e;

    e = load_error(R"({"kind": "ohman", "version": 1, )" + prov +
                   R"(, "vowels": {"AX": {}}, "consonants": {}})");
    EXPECT_NE(e.find("/vowels/AX: unknown phone \"AX\""), std::string::npos) << e;

    e = load_error(R"({"kind": "ohman", "version": 1, )" + prov +
                   R"(, "vowels": {"AA": {"jaw_rotation": 2.5}}, "consonants": {}})");
    EXPECT_NE(e.find("/vowels/AA/jaw_rotation: expected a number in [-0.1, 1], got 2.5"), std::string::npos) << e;
    EXPECT_NE(e.find("/vowels/AA/lip_rounding: missing field"), std::string::npos) << e;

    e = load_error(R"({"kind": "cohen-massaro", "version": 1, )" + prov +
                   R"(, "phones": {"P": {"c": 1, "params": {"jaw_rotaton": {}}}}})");
    EXPECT_NE(e.find("/phones/P/params/jaw_rotaton: unknown parameter \"jaw_rotaton\" (did you mean \"jaw_rotation\"?)"),
              std::string::npos)
        << e;

    e = load_error("{\"kind\": \"rule\",\n  \"version\": 1,,\n}");
    EXPECT_NE(e.find("m.json:2:"), std::string::npos) << e;
}

TEST(ModelFiles, MissingPhoneAtSynthesisIsAnInputError) {
    CohenMassaroModel model({{"sil", cm_phone(0, 1, 10, 10, 1)}});
    EXPECT_THROW(model.synthesize(three_segments(), 60.0), InputError);
}

TEST(Plot, SvgHasDominanceCurvesAndLabels) {
    const auto model = load_model(models_dir / "cohen-massaro.json");
    const std::string svg = synthesis_plot_svg(*model, three_segments(), Param::JawRotation, 60.0);
    EXPECT_EQ(svg.rfind("<svg", 0), 0u);
    // One dominance polyline per segment plus the trajectory.
    std::size_t polylines = 0;
    for (std::size_t pos = 0; (pos = svg.find("<polyline", pos)) != std::string::npos; ++pos) ++polylines;
    EXPECT_EQ(polylines, 4u);
    EXPECT_NE(svg.find(">AA</text>"), std::string::npos);
    EXPECT_NE(svg.find("dominance D(t)"), std::string::npos);
}

}  // namespace
}  // namespace avsi::synth
