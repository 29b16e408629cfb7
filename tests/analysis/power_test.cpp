// Power by simulation: reproducible across thread counts, calibrated under
// the null, increasing with subjects, labelled as simulation.
#include <filesystem>

#include <unistd.h>

#include <gtest/gtest.h>

#include "avsi/analysis/power.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::analysis {
namespace {

PowerSettings small(std::vector<double> means, std::size_t sims) {
    PowerSettings s;
    s.means_percent = std::move(means);
    s.subject_counts = {6, 24};
    s.sentences_per_cell = 6;
    s.keywords_per_sentence = 3;
    s.simulations = sims;
    s.seed = 42;
    return s;
}

TEST(Power, SameSeedSameResultWhateverTheThreadCount) {
    PowerSettings a = small({50, 60, 65}, 60);
    a.threads = 1;
    PowerSettings b = a;
    b.threads = 2;
    const auto ra = simulate_power(a), rb = simulate_power(b);
    ASSERT_EQ(ra.points.size(), rb.points.size());
    for (std::size_t i = 0; i < ra.points.size(); ++i) {
        EXPECT_EQ(ra.points[i].power_anova, rb.points[i].power_anova);
        EXPECT_EQ(ra.points[i].power_contrast, rb.points[i].power_contrast);
        EXPECT_EQ(ra.points[i].mean_percent, rb.points[i].mean_percent);
    }
    PowerSettings c = a;
    c.seed = 43;
    EXPECT_NE(simulate_power(c).points[1].mean_percent, ra.points[1].mean_percent);
}

TEST(Power, NullEffectRejectsAtAboutAlpha) {
    PowerSettings s = small({60, 60, 60}, 400);
    s.subject_counts = {12};
    const auto r = simulate_power(s);
    // 400 simulations: Monte Carlo SE of 0.05 is 0.011; allow 4 SE.
    EXPECT_NEAR(r.points[0].power_anova, 0.05, 0.045);
    EXPECT_NEAR(r.points[0].power_contrast, 0.05, 0.045);
    EXPECT_NEAR(r.points[0].mean_percent, 58.0, 6.0);  // random effects pull the mean towards 50
}

TEST(Power, GrowsWithSubjects) {
    const auto r = simulate_power(small({50, 58, 66}, 150));
    EXPECT_LT(r.points[0].power_anova, r.points[1].power_anova);
    EXPECT_GT(r.points[1].power_anova, 0.9);
    EXPECT_EQ(r.contrast, "c3 - c1");
    EXPECT_LE(r.points[1].power_anova_gg, r.points[1].power_anova);
}

TEST(Power, ParsesOptions) {
    EXPECT_EQ(parse_subject_counts("10..40"), (std::vector<std::size_t>{10, 15, 20, 25, 30, 35, 40}));
    EXPECT_EQ(parse_subject_counts("10..21:4"), (std::vector<std::size_t>{10, 14, 18, 21}));
    EXPECT_EQ(parse_subject_counts("12, 24"), (std::vector<std::size_t>{12, 24}));
    EXPECT_THROW(parse_subject_counts("ten"), InputError);
    EXPECT_EQ(parse_means("60,70.5"), (std::vector<double>{60, 70.5}));
    EXPECT_THROW(parse_means("60,100"), InputError);
    EXPECT_EQ(parse_contrast("2-1", 3), (std::pair<std::size_t, std::size_t>{1, 0}));
    EXPECT_EQ(parse_contrast("c3-c2", 3), (std::pair<std::size_t, std::size_t>{2, 1}));
    EXPECT_THROW(parse_contrast("4-1", 3), InputError);
    PowerSettings bad = small({60}, 10);
    EXPECT_THROW(simulate_power(bad), InputError);
}

TEST(Power, EveryOutputSaysSimulation) {
    const auto r = simulate_power(small({50, 70}, 20));
    const auto dir = std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_avsi_power_test");
    std::filesystem::remove_all(dir);
    write_power_files(dir, r);
    for (const char* f : {"power.csv", "power.json", "power.txt"}) {
        SCOPED_TRACE(f);
        EXPECT_NE(read_text_file(dir / f).find("simulation"), std::string::npos);
    }
    EXPECT_NE(power_table(r).find("Power by simulation"), std::string::npos);
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace avsi::analysis
