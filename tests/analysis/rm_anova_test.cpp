// Agreement with R (tests/data/analysis/<case>.expected.json, made by
// scripts/r/reference.R) for the ANOVA, sphericity and pairwise tests, plus
// edge cases: k = 2, singular covariance, missing cells, tiny p values.
#include <cmath>
#include <fstream>
#include <memory>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "avsi/analysis/descriptives.h"
#include "avsi/analysis/pairwise.h"
#include "avsi/analysis/rm_anova.h"
#include "avsi/analysis/scores.h"
#include "avsi/core/error.h"
#include "avsi/core/log.h"

namespace avsi::analysis {
namespace {

const std::string kDir = AVSI_TEST_DATA_DIR "/analysis/";

nlohmann::json load_expected(const std::string& name) {
    std::ifstream in(kDir + name + ".expected.json");
    EXPECT_TRUE(in) << "missing " << name << ".expected.json";
    return nlohmann::json::parse(in);
}

// |a - b| <= 1e-6 relative (absolute 1e-9 around 0).
::testing::AssertionResult close(double actual, double expected) {
    const double tol = std::max(1e-6 * std::fabs(expected), 1e-9);
    if (std::fabs(actual - expected) <= tol) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "got " << actual << ", R says " << expected;
}

struct Loaded {
    WithinData data;
    AnovaResult anova;
    std::vector<PairwiseComparison> pairs;
    std::vector<std::string> warnings;
};

Loaded run_case(const std::string& name) {
    auto sink = std::make_shared<MemorySink>();
    set_log_sink(sink);
    Loaded l;
    l.data = make_within_data(read_scores(kDir + name + ".csv"), name + ".csv");
    l.anova = rm_anova(l.data);
    l.pairs = pairwise_comparisons(l.data, l.anova);
    for (const auto& m : sink->messages())
        if (m.level == LogLevel::Warning) l.warnings.push_back(m.text);
    set_log_sink(nullptr);
    return l;
}

class AgreesWithR : public ::testing::TestWithParam<std::string> {};

TEST_P(AgreesWithR, AnovaSphericityAndPairwiseMatchReference) {
    const std::string name = GetParam();
    SCOPED_TRACE(name);
    const auto r = load_expected(name);
    const Loaded l = run_case(name);
    const AnovaResult& a = l.anova;
    ASSERT_EQ(a.n, r["n"].get<std::size_t>());
    ASSERT_EQ(a.k, r["k"].get<std::size_t>());
    EXPECT_EQ(a.dropped.size(), r["dropped"].size());
    EXPECT_TRUE(close(a.ss_conditions, r["ss_conditions"]));
    EXPECT_TRUE(close(a.ss_error, r["ss_error"]));
    EXPECT_TRUE(close(a.ss_subjects, r["ss_subjects"]));
    EXPECT_EQ(a.df_conditions, r["df_conditions"].get<double>());
    EXPECT_EQ(a.df_error, r["df_error"].get<double>());
    ASSERT_TRUE(a.F && a.p_value);
    EXPECT_TRUE(close(*a.F, r["F"]));
    EXPECT_TRUE(close(*a.p_value, r["p"]));
    EXPECT_TRUE(close(a.partial_eta_sq, r["pes"]));
    EXPECT_TRUE(close(a.generalized_eta_sq, r["ges"]));
    ASSERT_TRUE(a.greenhouse_geisser.epsilon && a.huynh_feldt.epsilon);
    EXPECT_TRUE(close(*a.greenhouse_geisser.epsilon, r["gg_epsilon"]));
    EXPECT_TRUE(close(*a.huynh_feldt.epsilon, r["hf_epsilon"]));
    EXPECT_TRUE(close(*a.greenhouse_geisser.p_value, r["gg_p"]));
    EXPECT_TRUE(close(*a.huynh_feldt.p_value, r["hf_p"]));
    EXPECT_TRUE(close(a.mauchly.W, r["mauchly_W"]));
    if (a.k > 2 && r["mauchly_W"].get<double>() > 0) {
        ASSERT_TRUE(a.mauchly.computable);
        EXPECT_TRUE(close(*a.mauchly.p_value, r["mauchly_p"]));
    }
    if (r.contains("car_mauchly_p") && !r["car_mauchly_p"].is_null()) {
        EXPECT_TRUE(close(*a.mauchly.p_value, r["car_mauchly_p"]));
        EXPECT_TRUE(close(*a.greenhouse_geisser.p_value, r["car_gg_p"]));
        EXPECT_TRUE(close(*a.huynh_feldt.epsilon, r["car_hf_epsilon"]));
        EXPECT_TRUE(close(*a.huynh_feldt.p_value, r["car_hf_p"]));
    }

    ASSERT_EQ(l.pairs.size(), r["pairwise"].size());
    for (std::size_t i = 0; i < l.pairs.size(); ++i) {
        const auto& c = l.pairs[i];
        const auto& e = r["pairwise"][i];
        SCOPED_TRACE(c.a + " - " + c.b);
        EXPECT_EQ(c.a, e["a"].get<std::string>());
        EXPECT_EQ(c.b, e["b"].get<std::string>());
        EXPECT_TRUE(close(c.mean_difference, e["mean_difference"]));
        EXPECT_TRUE(close(c.t_pooled.value_or(NAN), e["t_pooled"]));
        EXPECT_TRUE(close(*c.p_pooled, e["p_pooled"]));
        EXPECT_TRUE(close(c.ci_pooled_low, e["ci_pooled_low"]));
        EXPECT_TRUE(close(c.ci_pooled_high, e["ci_pooled_high"]));
        EXPECT_EQ(c.df_pooled, e["df_pooled"].get<double>());
        if (e["t"].is_null()) {
            EXPECT_FALSE(c.t.has_value()) << "R's t.test refused constant differences";
            continue;
        }
        ASSERT_TRUE(c.t && c.p_value);
        EXPECT_TRUE(close(*c.t, e["t"]));
        EXPECT_TRUE(close(*c.p_value, e["p"]));
        EXPECT_TRUE(close(*c.p_holm, e["p_holm"]));
        EXPECT_TRUE(close(*c.p_bonferroni, e["p_bonferroni"]));
        EXPECT_TRUE(close(c.ci_low, e["ci_low"]));
        EXPECT_TRUE(close(c.ci_high, e["ci_high"]));
        EXPECT_TRUE(close(*c.d_z, e["d_z"]));
    }
}

INSTANTIATE_TEST_SUITE_P(Cases, AgreesWithR,
                         ::testing::Values("balanced", "sphericity_violated", "k2", "hf_above_one", "tied",
                                           "missing_cell", "tiny_p"));

TEST(RmAnova, TwoConditionsAreTriviallySpherical) {
    const Loaded l = run_case("k2");
    EXPECT_EQ(l.anova.mauchly.W, 1.0);
    EXPECT_EQ(*l.anova.greenhouse_geisser.epsilon, 1.0);
    EXPECT_EQ(*l.anova.huynh_feldt.epsilon, 1.0);
    EXPECT_EQ(*l.anova.huynh_feldt.p_value, *l.anova.p_value);
    // With two conditions F is the square of the paired t.
    EXPECT_NEAR(*l.anova.F, std::pow(*l.pairs[0].t, 2), 1e-9 * *l.anova.F);
}

TEST(RmAnova, TiedConditionsGiveNotComputableMauchlyButEpsilons) {
    const Loaded l = run_case("tied");
    EXPECT_FALSE(l.anova.mauchly.computable);
    EXPECT_EQ(l.anova.mauchly.W, 0.0);
    EXPECT_FALSE(l.anova.mauchly.p_value.has_value());
    EXPECT_FALSE(l.anova.mauchly.note.empty());
    ASSERT_TRUE(l.anova.greenhouse_geisser.epsilon.has_value());
    EXPECT_TRUE(std::isfinite(*l.anova.greenhouse_geisser.epsilon));
}

TEST(RmAnova, MissingCellDropsSubjectsListwiseWithNamedWarning) {
    const Loaded l = run_case("missing_cell");
    ASSERT_EQ(l.anova.dropped.size(), 2u);
    EXPECT_EQ(l.anova.dropped[0].subject, "s04");
    EXPECT_EQ(l.anova.dropped[1].subject, "s09");
    EXPECT_EQ(l.anova.dropped[1].missing_conditions, std::vector<std::string>{"c3"});
    ASSERT_EQ(l.warnings.size(), 2u);
    EXPECT_NE(l.warnings[0].find("s04"), std::string::npos);
    EXPECT_NE(l.warnings[1].find("s09"), std::string::npos);
}

TEST(RmAnova, TinyPIsFiniteAndPositive) {
    const Loaded l = run_case("tiny_p");
    ASSERT_TRUE(l.anova.p_value.has_value());
    EXPECT_LT(*l.anova.p_value, 1e-80);
    EXPECT_GT(*l.anova.p_value, 0.0);
    EXPECT_TRUE(std::isfinite(*l.anova.greenhouse_geisser.p_value));
}

TEST(RmAnova, PerfectlyAdditiveDataHasNoF) {
    // Every subject = condition effect + subject offset: SS_error = 0.
    const auto data = make_within_data({"a", "b", "c"}, {"x", "y", "z"},
                                       {10, 20, 40, 15, 25, 45, 30, 40, 60});
    const AnovaResult a = rm_anova(data);
    EXPECT_FALSE(a.F.has_value());
    EXPECT_FALSE(a.mauchly.computable);
    EXPECT_FALSE(a.notes.empty());
}

TEST(RmAnova, FewerThanTwoCompleteSubjectsIsAnInputError) {
    Scores s;
    s.cells = {{"a", "x", 0, 0, 50.0}, {"a", "y", 0, 0, 60.0}, {"b", "x", 0, 0, 40.0}, {"b", "y", 0, 0, std::nullopt}};
    EXPECT_THROW(make_within_data(s), InputError);
}

TEST(Pairwise, HolmMatchesHandComputation) {
    // R: p.adjust(c(0.01, 0.04, 0.03, 0.5), "holm") = 0.04 0.09 0.09 0.5
    const auto h = holm_adjust({0.01, 0.04, 0.03, 0.5});
    EXPECT_NEAR(*h[0], 0.04, 1e-15);
    EXPECT_NEAR(*h[1], 0.09, 1e-15);
    EXPECT_NEAR(*h[2], 0.09, 1e-15);
    EXPECT_NEAR(*h[3], 0.5, 1e-15);
}

TEST(Descriptives, CousineauMoreyIntervalsAreNarrowerThanBetweenSubject) {
    const Loaded l = run_case("balanced");
    const auto d = describe(l.data);
    ASSERT_EQ(d.size(), 6u);
    for (const auto& s : d) {
        EXPECT_LT(s.se_within, s.sd / std::sqrt(double(s.n)));
        EXPECT_NEAR((s.ci_low + s.ci_high) / 2.0, s.mean, 1e-9);
    }
    // The within-subject SEs, squared and summed, give the ANOVA's mean square
    // error: sum_j se_j^2 * n / k = MS_error (Morey 2008).
    double sum = 0.0;
    for (const auto& s : d) sum += s.se_within * s.se_within;
    const double k = 6.0, n = 25.0;
    EXPECT_NEAR(sum * n / k, l.anova.ms_error, 1e-9 * l.anova.ms_error);
}

}  // namespace
}  // namespace avsi::analysis
