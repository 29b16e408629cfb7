// Objective evaluation (Table 2 measures): RMSE as % of range and Pearson ρ,
// per subset (non-silence, vowels, consonants), missing values left out.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "avsi/core/files.h"
#include "avsi/learn/evaluation.h"
#include "support/temp_dir.h"

using namespace avsi;
using namespace avsi::synth;
using namespace avsi::learn;

namespace {

// 1 s at 10 fps: sil 0–0.2, AA 0.2–0.6, P 0.6–0.8, sil 0.8–1.0.
CorpusUtterance utterance() {
    CorpusUtterance u;
    u.id = "u";
    u.phones = {{"sil", 0.0, 0.2, false}, {"AA", 0.2, 0.6, true}, {"P", 0.6, 0.8, false}, {"sil", 0.8, 1.0, false}};
    u.track.fps = 10.0;
    u.track.present[index(Param::JawRotation)] = true;
    u.track.present[index(Param::LipRounding)] = true;
    for (int k = 0; k < 10; ++k) {
        Frame f;
        f.fill(std::nan(""));
        f[index(Param::JawRotation)] = 0.1 * k;
        f[index(Param::LipRounding)] = k % 2 ? 0.3 : -0.2;
        u.track.frames.push_back(f);
    }
    return u;
}

PredictFunction copy_plus(double jaw_offset) {
    return [jaw_offset](const PhoneSequence&, std::span<const double> times, std::vector<Frame>& out) {
        const CorpusUtterance u = utterance();
        out.resize(times.size());
        for (std::size_t k = 0; k < times.size(); ++k) {
            out[k] = u.track.frames[k];
            out[k][index(Param::JawRotation)] += jaw_offset;
        }
    };
}

constexpr auto all = static_cast<std::size_t>(FrameSubset::AllNonSilence);
constexpr auto vowels = static_cast<std::size_t>(FrameSubset::Vowels);
constexpr auto consonants = static_cast<std::size_t>(FrameSubset::Consonants);

}  // namespace

TEST(Evaluation, PerfectPredictionHasZeroErrorAndUnitCorrelation) {
    const auto s = evaluate_predictors({utterance()}, {{"copy", copy_plus(0.0)}});
    const Score jaw = s[0].per_param[all][index(Param::JawRotation)];
    EXPECT_EQ(jaw.frames, 6u);  // frames 2–7: AA and P, not silence
    EXPECT_DOUBLE_EQ(jaw.rmse_percent, 0.0);
    EXPECT_NEAR(jaw.pearson, 1.0, 1e-12);
    EXPECT_EQ(s[0].per_param[vowels][index(Param::JawRotation)].frames, 4u);
    EXPECT_EQ(s[0].per_param[consonants][index(Param::JawRotation)].frames, 2u);
    // Parameters the corpus lacks are left out of the mean.
    EXPECT_EQ(s[0].per_param[all][index(Param::JawShift)].frames, 0u);
    EXPECT_DOUBLE_EQ(s[0].mean[all].rmse_percent, 0.0);
}

TEST(Evaluation, OffsetGivesRmseAsPercentOfRange) {
    // jaw_rotation's range is 1.1; an offset of 0.11 is 10 % of it, ρ stays 1.
    const auto s = evaluate_predictors({utterance()}, {{"offset", copy_plus(0.11)}});
    const Score jaw = s[0].per_param[all][index(Param::JawRotation)];
    EXPECT_NEAR(jaw.rmse_percent, 10.0, 1e-9);
    EXPECT_NEAR(jaw.pearson, 1.0, 1e-12);
    // Mean over the two present parameters: (10 + 0) / 2.
    EXPECT_NEAR(s[0].mean[all].rmse_percent, 5.0, 1e-9);
    EXPECT_NEAR(s[0].mean[all].pearson, 1.0, 1e-12);
}

TEST(Evaluation, AnticorrelatedPredictionHasRhoMinusOne) {
    const PredictFunction flipped = [](const PhoneSequence&, std::span<const double> times, std::vector<Frame>& out) {
        out.assign(times.size(), Frame{});
        for (std::size_t k = 0; k < times.size(); ++k) out[k][index(Param::JawRotation)] = 1.0 - 0.1 * double(k);
    };
    const auto s = evaluate_predictors({utterance()}, {{"flipped", flipped}});
    EXPECT_NEAR(s[0].per_param[all][index(Param::JawRotation)].pearson, -1.0, 1e-12);
    // A constant prediction has no correlation: ρ is undefined, not 0.
    EXPECT_TRUE(std::isnan(s[0].per_param[all][index(Param::LipRounding)].pearson));
}

TEST(Evaluation, TablesHaveEverySubsetAndModel) {
    const auto s = evaluate_predictors({utterance()}, {{"a", copy_plus(0.0)}, {"b", copy_plus(0.11)}});
    const std::string md = scores_markdown(s, "caption");
    EXPECT_NE(md.find("| all non-silence | 0.00 | 1.0000 | 5.00 | 1.0000 |"), std::string::npos) << md;
    EXPECT_NE(md.find("| vowels |"), std::string::npos);
    EXPECT_NE(md.find("| consonants |"), std::string::npos);
    const std::string csv = scores_csv(s);
    EXPECT_NE(csv.find("b,all non-silence,jaw_rotation,10.0000,1.000000,6\n"), std::string::npos) << csv;
}

TEST(Evaluation, PlotIsAnSvgWithEveryCurve) {
    const auto dir = test::temp_dir("eval_plot");
    const CorpusUtterance u = utterance();
    write_trajectory_plot_svg(dir / "p.svg", u, Param::JawRotation,
                              {{"model-a", std::vector<double>(10, 0.2)}, {"model-b", std::vector<double>(10, 0.4)}});
    const std::string svg = read_text_file(dir / "p.svg");
    EXPECT_NE(svg.find("<svg"), std::string::npos);
    // Target + 2 models + axes: at least 3 stroked paths beyond the frame.
    std::size_t paths = 0;
    for (std::size_t pos = 0; (pos = svg.find("<path", pos)) != std::string::npos; ++pos) ++paths;
    EXPECT_GE(paths, 4u);
}

// Phonetic columns: a hand-made articulation function (aperture 20 mm and
// lower lip to incisors 5 mm per unit of jaw rotation) on a complete track
// whose jaw opens 0.1 per frame; a predictor that keeps the jaw shut closes
// the /p/ and reaches the /f/, the track itself does neither.
TEST(Evaluation, PhoneticColumnsCountClosuresAndMeasureTheErrorAtTheSegments) {
    CorpusUtterance u;
    u.id = "p";
    u.phones = {{"sil", 0.0, 0.2, false}, {"AA", 0.2, 0.6, true}, {"P", 0.6, 0.8, false}, {"F", 0.8, 0.9, false},
                {"sil", 0.9, 1.0, false}};
    u.track.fps = 10.0;
    u.track.present.fill(true);
    for (int k = 0; k < 10; ++k) {
        Frame f{};
        f[index(Param::JawRotation)] = 0.1 * k;
        u.track.frames.push_back(f);
    }
    const ArticulationFunction articulation = [](const Trajectory& t) {
        std::vector<ArticulationMeasures> out;
        for (std::size_t k = 0; k < t.size(); ++k) {
            ArticulationMeasures m;
            m.time_s = t.time_s(k);
            m.aperture_mid_mm = m.aperture_min_mm = m.aperture_max_mm = m.aperture_all_min_mm =
                20.0 * t.frames[k][index(Param::JawRotation)];
            m.lip_to_incisors_mm = 5.0 * t.frames[k][index(Param::JawRotation)];
            out.push_back(m);
        }
        return out;
    };
    const PredictFunction shut = [](const PhoneSequence&, std::span<const double> times, std::vector<Frame>& out) {
        out.assign(times.size(), Frame{});
    };
    const auto s = evaluate_predictors({u}, {{"shut", shut}}, articulation);
    ASSERT_TRUE(s[0].phonetic.has_value());
    const PhoneticScores& p = *s[0].phonetic;
    EXPECT_EQ(p.bilabials, 1u);
    EXPECT_EQ(p.bilabials_closed, 1u);
    EXPECT_EQ(p.labiodentals, 1u);
    EXPECT_EQ(p.labiodentals_reached, 1u);
    EXPECT_NEAR(p.aperture_error_mm, (12.0 + 14.0) / 2.0, 1e-9);  // frames 6 and 7 of the /p/
    EXPECT_NEAR(p.lip_to_incisors_error_mm, 4.0, 1e-9);           // frame 8 of the /f/
    const PhoneticScores r = reference_phonetic_scores({u}, articulation);
    EXPECT_EQ(r.bilabials_closed, 0u);
    EXPECT_EQ(r.labiodentals_reached, 0u);
    EXPECT_DOUBLE_EQ(r.aperture_error_mm, 0.0);
    const std::string csv = phonetic_csv(r, s);
    EXPECT_NE(csv.find("\nreference,1,0,0.0000,1,0,0.0000,0.0000,0.0000\n"), std::string::npos) << csv;
    EXPECT_NE(csv.find("\nshut,1,1,1.0000,1,1,1.0000,13.0000,4.0000\n"), std::string::npos) << csv;
    // Without an articulation function there are no phonetic columns.
    EXPECT_FALSE(evaluate_predictors({u}, {{"shut", shut}})[0].phonetic.has_value());
}
