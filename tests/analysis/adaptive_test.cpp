// Adaptive SRT procedures (analysis/adaptive.h): the step rules against
// sequences computed by hand, the psychometric ML fit against a brute-force
// likelihood search and a finite-difference Fisher information, and
// simulated listeners with a known psychometric function.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>

#include "avsi/analysis/adaptive.h"
#include "avsi/core/error.h"
#include "avsi/core/protocol.h"

using namespace avsi;
using namespace avsi::analysis;

namespace {

TrackSettings hint_settings() {
    TrackSettings s;
    s.procedure = AdaptiveProcedure::Sentence;
    s.start_db = 0.0;
    s.large_step_db = 4.0;
    s.large_steps = 4;
    s.small_step_db = 2.0;
    s.repeat_first = true;
    s.srt_from = 5;
    s.srt_include_next = true;
    return s;
}

TrackSettings bk_settings() {
    TrackSettings s;
    s.procedure = AdaptiveProcedure::Word;
    s.start_db = 0.0;
    s.target = 0.5;
    s.slope_per_db = 0.15;
    s.f_start = 1.5;
    s.f_ratio = 1.41;
    s.f_min = 0.1;
    return s;
}

double loglik(const std::vector<PsychometricPoint>& pts, double l50, double slope) {
    double ll = 0.0;
    for (const auto& p : pts) {
        const double q = 1.0 / (1.0 + std::exp(-4.0 * slope * (p.level_db - l50)));
        ll += p.correct * std::log(q) + (p.trials - p.correct) * std::log(1.0 - q);
    }
    return ll;
}

}  // namespace

TEST(AdaptiveSentence, StepsMatchAHandComputedHintSequence) {
    AdaptiveTrack t(hint_settings());
    // (correct of 3) per presentation and the level it was presented at, by hand:
    // s1 at 0 wrong → repeat at +4; s1 at 4 right → large step down to 0;
    // s2 right → −4; s3 wrong → 0; s4 right → −4; s5 right (small step) → −6;
    // s6 wrong → −4; s7 wrong → −2; s8 right → −4.
    const int correct[] = {2, 3, 3, 1, 3, 3, 0, 2, 3};
    const double level[] = {0, 4, 0, -4, 0, -4, -6, -4, -2};
    const int sentence[] = {1, 1, 2, 3, 4, 5, 6, 7, 8};
    const bool reversal[] = {false, true, false, true, true, false, true, false, true};
    for (int i = 0; i < 9; ++i) {
        SCOPED_TRACE(i);
        EXPECT_DOUBLE_EQ(t.level_db(), level[i]);
        const TrackStep& s = t.record(3, correct[i]);
        EXPECT_EQ(s.sentence, sentence[i]);
        EXPECT_EQ(s.reversal, reversal[i]);
    }
    EXPECT_TRUE(t.steps()[0].repeat);
    EXPECT_EQ(t.steps()[1].attempt, 2);
    EXPECT_DOUBLE_EQ(t.level_db(), -4.0);
    EXPECT_EQ(t.reversals(), 5);
    EXPECT_EQ(t.sentences(), 8);
    // SRT: sentences 5..8 (−4, −6, −4, −2) and the next level −4 → −4.0 dB;
    // SD √2, SE √2/√5.
    const SrtEstimate e = estimate_srt(hint_settings(), t.steps());
    ASSERT_TRUE(e.valid);
    EXPECT_EQ(e.levels, 5);
    EXPECT_DOUBLE_EQ(e.srt_db, -4.0);
    EXPECT_NEAR(e.se_db, std::sqrt(2.0) / std::sqrt(5.0), 1e-12);
}

TEST(AdaptiveSentence, FirstSentenceRepeatsStopAtTheLimitAndTheBoundIsRecorded) {
    TrackSettings s = hint_settings();
    s.max_first_repeats = 2;
    s.max_db = 9.0;
    AdaptiveTrack t(s);
    t.record(3, 0);  // at 0 → repeat at 4
    t.record(3, 0);  // at 4 → repeat at 8
    EXPECT_TRUE(t.repeating());
    const TrackStep& third = t.record(3, 0);  // third attempt: limit reached, an ordinary up step, bounded at 9
    EXPECT_FALSE(third.repeat);
    EXPECT_TRUE(third.at_bound);
    EXPECT_DOUBLE_EQ(third.next_level_db, 9.0);
    EXPECT_DOUBLE_EQ(third.step_db, 1.0);
    EXPECT_EQ(t.sentences(), 1);
    EXPECT_EQ(t.record(3, 3).sentence, 2);
}

TEST(AdaptiveSentence, WithoutRepeatTheFirstWrongSentenceStepsUpOnce) {
    TrackSettings s = hint_settings();
    s.repeat_first = false;
    AdaptiveTrack t(s);
    const TrackStep& a = t.record(3, 2);
    EXPECT_FALSE(a.repeat);
    EXPECT_DOUBLE_EQ(a.next_level_db, 4.0);
    EXPECT_EQ(t.record(3, 3).sentence, 2);
}

TEST(AdaptiveWord, StepsMatchBrandKollmeierByHand) {
    AdaptiveTrack t(bk_settings());
    // ΔL = −f(i)(prop − 0.5)/0.15, f(i) = 1.5·1.41^−i:
    //  0 → 3/3: −1.5·0.5/0.15 = −5            → −5
    // −5 → 2/3: −1.5·(1/6)/0.15 = −5/3         → −6.666667
    // −6.67 → 0/3: +5 (reversal, i = 1)         → −1.666667
    // −1.67 → 1/3: +(1.5/1.41)(1/6)/0.15 = +1.182033 → −0.484634
    // −0.48 → 3/3: −(1.5/1.41)·0.5/0.15 = −3.546099 (reversal, i = 2) → −4.030733
    const int correct[] = {3, 2, 0, 1, 3};
    const double next[] = {-5.0, -20.0 / 3.0, -5.0 / 3.0, -5.0 / 3.0 + 1.5 / 1.41 / 6.0 / 0.15,
                           -5.0 / 3.0 + 1.5 / 1.41 / 6.0 / 0.15 - 1.5 / 1.41 * 0.5 / 0.15};
    const int reversals[] = {0, 0, 1, 1, 2};
    for (int i = 0; i < 5; ++i) {
        SCOPED_TRACE(i);
        const TrackStep& s = t.record(3, correct[i]);
        EXPECT_NEAR(s.next_level_db, next[i], 1e-12);
        EXPECT_EQ(s.reversals, reversals[i]);
    }
    EXPECT_NEAR(next[3], -0.484634, 1e-6);
    EXPECT_NEAR(next[4], -4.030733, 1e-6);
    EXPECT_DOUBLE_EQ(bk_step_factor(bk_settings(), 0), 1.5);
    EXPECT_NEAR(bk_step_factor(bk_settings(), 2), 1.5 / (1.41 * 1.41), 1e-12);
    EXPECT_DOUBLE_EQ(bk_step_factor(bk_settings(), 20), 0.1);  // 1.5·1.41^−20 ≈ 0.0016 < f_min
}

TEST(AdaptiveWord, ATargetOf08StepsDownOnlyWhenAboveIt) {
    TrackSettings s = bk_settings();
    s.target = 0.8;
    AdaptiveTrack t(s);
    // 2/3 = 0.667 < 0.8: up by 1.5·0.1333/0.15 = 1.3333.
    EXPECT_NEAR(t.record(3, 2).next_level_db, 1.5 * (0.8 - 2.0 / 3.0) / 0.15, 1e-12);
}

TEST(AdaptiveTrack, RejectsImpossibleScoresAndSettings) {
    AdaptiveTrack t(hint_settings());
    EXPECT_THROW(t.record(3, 4), InputError);
    EXPECT_THROW(t.record(0, 0), InputError);
    TrackSettings bad = hint_settings();
    bad.start_db = 50.0;  // outside [−30, 30]
    bad.small_step_db = 0.0;
    try {
        AdaptiveTrack x(bad);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.diagnostics().size(), 2u);
        EXPECT_NE(std::string(e.what()).find("adaptive.start_snr_db"), std::string::npos) << e.what();
    }
}

TEST(AdaptiveTrack, ReplayingTheSameScoresGivesTheSameLevels) {
    Rng rng(7);
    SimulatedListener listener{-4.0, 0.12, 3};
    for (const TrackSettings& s : {hint_settings(), bk_settings()}) {
        AdaptiveTrack a(s);
        std::vector<int> scores;
        while (a.sentences() < 25) {
            scores.push_back(simulate_response(listener, a.level_db(), rng));
            a.record(3, scores.back());
        }
        AdaptiveTrack b(s);
        for (std::size_t i = 0; i < scores.size(); ++i) {
            ASSERT_DOUBLE_EQ(b.level_db(), a.steps()[i].level_db);
            b.record(3, scores[i]);
        }
        EXPECT_DOUBLE_EQ(b.level_db(), a.level_db());
    }
}

TEST(PsychometricFit, SymmetricDataPutL50AtTheCentre) {
    const std::vector<PsychometricPoint> pts = {{-2, 10, 2}, {0, 10, 5}, {2, 10, 8}};
    const PsychometricFit f = fit_psychometric(pts);
    ASSERT_TRUE(f.converged) << f.note;
    EXPECT_NEAR(f.l50_db, 0.0, 1e-9);
    // By hand: the score equation at L50 = 0 is Σ x (c − n p(x)) = 0 →
    // 2·(8 − 10 p(2)) − 2·(2 − 10 p(−2)) = 0 → p(2) = 0.8 → 4s·2 = logit(0.8).
    EXPECT_NEAR(f.slope_per_db, std::log(4.0) / 8.0, 1e-9);
    EXPECT_NEAR(f.p(2.0), 0.8, 1e-9);
}

TEST(PsychometricFit, MatchesABruteForceLikelihoodSearchAndTheFiniteDifferenceInformation) {
    const std::vector<PsychometricPoint> pts = {{-10, 10, 1}, {-8, 12, 2}, {-6, 9, 4},
                                                {-4, 10, 6}, {-2, 11, 9}, {0, 10, 9}};
    const PsychometricFit f = fit_psychometric(pts);
    ASSERT_TRUE(f.converged) << f.note;
    // Grid search, then a finer grid around the best point (a different algorithm).
    double best_l = 0, best_s = 0, best = -std::numeric_limits<double>::infinity();
    for (double l = -10; l <= 0; l += 0.01)
        for (double s = 0.01; s <= 0.5; s += 0.001)
            if (const double ll = loglik(pts, l, s); ll > best) best = ll, best_l = l, best_s = s;
    for (double l = best_l - 0.01; l <= best_l + 0.01; l += 0.0001)
        for (double s = best_s - 0.001; s <= best_s + 0.001; s += 0.00001)
            if (const double ll = loglik(pts, l, s); ll > best) best = ll, best_l = l, best_s = s;
    EXPECT_NEAR(f.l50_db, best_l, 2e-4);
    EXPECT_NEAR(f.slope_per_db, best_s, 2e-5);
    EXPECT_NEAR(f.log_likelihood, best, 1e-6);
    // SE of L50 from the numeric Hessian of the log-likelihood in (L50, s).
    const double h1 = 1e-3, h2 = 1e-4;
    const double l = f.l50_db, s = f.slope_per_db;
    const double d_ll = (loglik(pts, l + h1, s) - 2 * loglik(pts, l, s) + loglik(pts, l - h1, s)) / (h1 * h1);
    const double d_ss = (loglik(pts, l, s + h2) - 2 * loglik(pts, l, s) + loglik(pts, l, s - h2)) / (h2 * h2);
    const double d_ls = (loglik(pts, l + h1, s + h2) - loglik(pts, l + h1, s - h2) - loglik(pts, l - h1, s + h2) +
                         loglik(pts, l - h1, s - h2)) /
                        (4 * h1 * h2);
    // Inverse of the observed information [[−d_ll, −d_ls], [−d_ls, −d_ss]].
    const double det = d_ll * d_ss - d_ls * d_ls;
    const double var_l = -d_ss / det;
    const double var_s = -d_ll / det;
    EXPECT_NEAR(f.se_l50_db, std::sqrt(var_l), 1e-3 * std::sqrt(var_l));
    EXPECT_NEAR(f.se_slope, std::sqrt(var_s), 1e-3 * std::sqrt(var_s));
}

TEST(PsychometricFit, FixedSlopeFitsOnlyL50) {
    const std::vector<PsychometricPoint> pts = {{-4, 10, 3}, {0, 10, 5}, {4, 10, 9}};
    const PsychometricFit f = fit_psychometric(pts, 0.1);
    ASSERT_TRUE(f.converged);
    EXPECT_TRUE(f.slope_fixed);
    EXPECT_DOUBLE_EQ(f.slope_per_db, 0.1);
    double best_l = 0, best = -std::numeric_limits<double>::infinity();
    for (double l = -10; l <= 10; l += 0.0001)
        if (const double ll = loglik(pts, l, 0.1); ll > best) best = ll, best_l = l;
    EXPECT_NEAR(f.l50_db, best_l, 2e-4);
}

TEST(PsychometricFit, NoCrossingMeansNoEstimate) {
    EXPECT_FALSE(fit_psychometric({{-2, 3, 3}, {0, 3, 3}}).converged);
    EXPECT_FALSE(fit_psychometric({{-2, 3, 0}, {0, 3, 0}}).converged);
    const PsychometricFit separated = fit_psychometric({{-6, 3, 0}, {-4, 3, 0}, {-2, 3, 3}, {0, 3, 3}});
    EXPECT_FALSE(separated.converged);
    EXPECT_NE(separated.note.find("separate"), std::string::npos) << separated.note;
    EXPECT_THROW(fit_psychometric({{0, 3, 4}}), InputError);
}

// Simulated listeners, seeded: each procedure's estimate is unbiased for the
// level it targets and its spread is about 1 dB for 20–30 sentences.
TEST(AdaptiveSimulation, HintSentenceProcedureIsUnbiasedWithAboutOneDbSpread) {
    SrtSimulationSettings s;
    s.track = hint_settings();
    s.listener = {-6.0, 0.15, 3};
    s.sentence_counts = {20, 30};
    s.listeners = 400;
    s.seed = 23;
    s.start_offset_sd_db = 2.0;
    const SrtSimulationResult r = simulate_srt(s);
    // The sentence is right when all 3 keywords are: p^3 = 0.5 → p = 0.794.
    const double truth = -6.0 + std::log(std::pow(0.5, 1.0 / 3) / (1 - std::pow(0.5, 1.0 / 3))) / 0.6;
    for (const auto& row : r.rows) {
        SCOPED_TRACE(row.estimator + " " + std::to_string(row.sentences));
        EXPECT_NEAR(row.true_db, truth, 1e-12);
        EXPECT_GE(row.estimates, 390);
        EXPECT_LT(std::fabs(row.bias_db), 0.35);
        EXPECT_GT(row.sd_db, 0.4);
        EXPECT_LT(row.sd_db, 1.6);
    }
    // More sentences, less spread (mean of levels).
    EXPECT_LT(r.rows[2].sd_db, r.rows[0].sd_db);
}

TEST(AdaptiveSimulation, BrandKollmeierWordProcedureIsUnbiasedForBothEstimators) {
    SrtSimulationSettings s;
    s.track = bk_settings();
    s.track.srt_from = 5;
    s.listener = {-6.0, 0.15, 3};
    s.sentence_counts = {20, 30};
    s.listeners = 400;
    s.seed = 2002;
    s.start_offset_sd_db = 2.0;
    const SrtSimulationResult r = simulate_srt(s);
    for (const auto& row : r.rows) {
        SCOPED_TRACE(row.estimator + " " + std::to_string(row.sentences));
        EXPECT_DOUBLE_EQ(row.true_db, -6.0);
        EXPECT_GE(row.estimates, 390);
        EXPECT_LT(std::fabs(row.bias_db), 0.35);
        EXPECT_GT(row.sd_db, 0.3);
        EXPECT_LT(row.sd_db, 1.6);
    }
}

TEST(AdaptiveSimulation, AnEightyPercentTargetConvergesOnTheEightyPercentLevel) {
    SrtSimulationSettings s;
    s.track = bk_settings();
    s.track.target = 0.8;
    s.listener = {-6.0, 0.15, 3};
    s.sentence_counts = {30};
    s.listeners = 300;
    s.seed = 80;
    const SrtSimulationResult r = simulate_srt(s);
    const double truth = -6.0 + std::log(4.0) / 0.6;  // logit(0.8) / (4·0.15)
    for (const auto& row : r.rows) {
        SCOPED_TRACE(row.estimator);
        EXPECT_NEAR(row.true_db, truth, 1e-12);
        EXPECT_LT(std::fabs(row.bias_db), 0.5);
    }
}

TEST(AdaptiveSimulation, IsDeterministicForASeed) {
    SrtSimulationSettings s;
    s.track = hint_settings();
    s.sentence_counts = {20};
    s.listeners = 50;
    const auto a = simulate_srt(s), b = simulate_srt(s);
    ASSERT_EQ(a.rows.size(), b.rows.size());
    for (std::size_t i = 0; i < a.rows.size(); ++i) EXPECT_DOUBLE_EQ(a.rows[i].mean_db, b.rows[i].mean_db);
    s.seed = 2;
    EXPECT_NE(simulate_srt(s).rows[0].mean_db, a.rows[0].mean_db);
}

TEST(AdaptiveProtocol, ReadsTheSectionAndReportsEveryProblem) {
    const std::string base = R"([experiment]
name = "t"
seed = 1
[corpus]
sentences = ")" + std::string(AVSI_TEST_DATA_DIR) + R"(/adaptive/corpus.csv"
[[condition]]
name = "audio-only"
face = "still"
[[condition]]
name = "av"
face = "still"
[design]
lists = 2
sentences_per_list = 10
warmup = 0
practice = 0
)";
    const Protocol p = parse_protocol(base + "[adaptive]\nprocedure = \"word\"\ntarget = 0.8\nstart_snr_db = -4\n"
                                             "reference = \"audio-only\"\nestimate = \"ml\"\n",
                                      "study.toml");
    const AdaptiveProtocol a = adaptive_protocol(p);
    EXPECT_TRUE(a.enabled);
    EXPECT_EQ(a.track.procedure, AdaptiveProcedure::Word);
    EXPECT_DOUBLE_EQ(a.track.target, 0.8);
    EXPECT_DOUBLE_EQ(a.track.start_db, -4.0);
    EXPECT_EQ(a.track.estimator, SrtEstimator::MaximumLikelihood);
    EXPECT_FALSE(adaptive_protocol(parse_protocol(base, "study.toml")).enabled);
    try {
        adaptive_protocol(parse_protocol(
            base + "[adaptive]\nvariable = \"band\"\nreference = \"visual\"\nsmall_step = 2\nsrt_from = 11\n", "study.toml"));
        FAIL() << "accepted";
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("study.toml:18:12: error: adaptive.variable"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.reference"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.small_step"), std::string::npos) << m;
        EXPECT_NE(m.find("did you mean"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.srt_from"), std::string::npos) << m;
    }
}

namespace {

// The test corpus with two vocoded conditions and an [adaptive] section.
Protocol list_protocol(const std::string& adaptive, const std::string& second_audio = "vocoded") {
    return parse_protocol(R"([experiment]
name = "t"
seed = 1
[corpus]
sentences = ")" + std::string(AVSI_TEST_DATA_DIR) + R"(/adaptive/corpus.csv"
[[condition]]
name = "audio-only"
face = "still"
[[condition]]
name = "av"
face = "still"
audio = ")" + second_audio + R"("
[design]
lists = 2
sentences_per_list = 10
warmup = 0
practice = 0
[adaptive]
)" + adaptive,
                          "study.toml");
}

}  // namespace

// The masker's stage and timing: before vocoding with a 500 ms lead and
// tail by default, as the methods text says; "after" and other timings on
// request; bad values and list variables refused at the key.
TEST(AdaptiveProtocol, TheMaskerGoesInBeforeVocodingOverTheWholePresentationByDefault) {
    const AdaptiveProtocol a = adaptive_protocol(list_protocol(""));
    EXPECT_EQ(a.noise_stage, MaskerStage::BeforeVocoding);
    EXPECT_DOUBLE_EQ(a.noise_lead_s, 0.5);
    EXPECT_DOUBLE_EQ(a.noise_tail_s, 0.5);
    const std::string text = masker_description(a);
    EXPECT_NE(text.find("Masker: speech-shaped noise (the long-term spectrum of each sentence), added to the speech "
                        "before vocoding"),
              std::string::npos)
        << text;
    EXPECT_NE(text.find("it started 500 ms before the stimulus (the face shown at rest) and ended 500 ms after it, "
                        "with 20 ms raised-cosine ramps"),
              std::string::npos)
        << text;
    const AdaptiveProtocol after =
        adaptive_protocol(list_protocol("noise_stage = \"after\"\nnoise_lead_ms = 0\nnoise_tail_ms = 0\n"));
    EXPECT_EQ(after.noise_stage, MaskerStage::AfterVocoding);
    EXPECT_NE(masker_description(after).find("added to the presented audio after vocoding"), std::string::npos);
    EXPECT_NE(masker_description(after).find("it ran exactly as long as the stimulus"), std::string::npos);
    try {
        adaptive_protocol(list_protocol("noise_stage = \"during\"\nnoise_lead_ms = -5\n"));
        FAIL() << "accepted";
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("adaptive.noise_stage"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.noise_lead_ms"), std::string::npos) << m;
    }
    try {
        adaptive_protocol(list_protocol("variable = \"bands\"\nlevels = [2, 4]\nnoise_stage = \"before\"\n"));
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("adaptive.noise_stage: expected only with variable = \"snr\""),
                  std::string::npos)
            << e.what();
    }
    EXPECT_EQ(masker_description(adaptive_protocol(list_protocol("variable = \"bands\"\nlevels = [2, 4]\n"))), "");
}

TEST(AdaptiveListVariable, BandTrackStepsByPositionOnTheLevelsAsComputedByHand) {
    const AdaptiveProtocol a = adaptive_protocol(
        list_protocol("variable = \"bands\"\nlevels = [1, 2, 3, 4, 6, 8, 12, 16]\nstart_level = 4\n"
                      "large_step_levels = 2\nlarge_steps = 2\nsmall_step_levels = 1\nrepeat_first = false\n"
                      "srt_from = 3\npractice_level = 12\n"));
    ASSERT_TRUE(a.list_variable());
    EXPECT_EQ(a.unit(), "bands");
    EXPECT_DOUBLE_EQ(a.practice_level, 12.0);
    EXPECT_DOUBLE_EQ(a.track.start_db, 3.0);  // position of 4 bands
    EXPECT_DOUBLE_EQ(a.track.min_db, 0.0);
    EXPECT_DOUBLE_EQ(a.track.max_db, 7.0);
    AdaptiveTrack t(a.track);
    // Sentence by sentence (3 keywords): right, wrong, wrong, then right five times.
    const std::vector<int> correct{3, 1, 2, 3, 3, 3, 3, 3};
    for (int c : correct) t.record(3, c);
    const auto steps = in_units(a, t.steps());
    // By hand: 4 -(2 positions)-> 2 -(+2)-> 4 -(+1, small from sentence 3)-> 6 -> 4 -> 3 -> 2 -> 1 -> 1 (bound).
    const std::vector<double> level{4, 2, 4, 6, 4, 3, 2, 1}, next{2, 4, 6, 4, 3, 2, 1, 1};
    ASSERT_EQ(steps.size(), level.size());
    for (std::size_t i = 0; i < steps.size(); ++i) {
        SCOPED_TRACE(i);
        EXPECT_DOUBLE_EQ(steps[i].level_db, level[i]);
        EXPECT_DOUBLE_EQ(steps[i].next_level_db, next[i]);
        EXPECT_DOUBLE_EQ(steps[i].step_db, next[i] - level[i]);
    }
    EXPECT_TRUE(steps.back().at_bound);
    EXPECT_FALSE(steps[6].at_bound);
    EXPECT_TRUE(steps[1].reversal);  // down, then up
    EXPECT_TRUE(steps[3].reversal);  // up, then down
    // Threshold: the levels of sentences 3..8 (4, 6, 4, 3, 2, 1) and the next one (1), in bands.
    const SrtEstimate e = estimate_srt(a.track, steps);
    ASSERT_TRUE(e.valid);
    EXPECT_NEAR(e.srt_db, (4.0 + 6 + 4 + 3 + 2 + 1 + 1) / 7.0, 1e-12);
    EXPECT_THROW(a.value_of(8.0), std::logic_error);
    EXPECT_THROW(a.value_of(0.5), std::logic_error);
}

TEST(AdaptiveListVariable, CutoffLevelsDefaultToTheMiddleStartAndTheTopPractice) {
    const AdaptiveProtocol a =
        adaptive_protocol(list_protocol("variable = \"cutoff\"\nlevels = [4, 8, 16.5, 32, 64]\n"));
    EXPECT_EQ(a.unit(), "Hz");
    EXPECT_EQ(a.variable, AdaptiveVariable::CutoffHz);
    EXPECT_DOUBLE_EQ(a.value_of(a.track.start_db), 16.5);
    EXPECT_DOUBLE_EQ(a.practice_level, 64.0);
    EXPECT_DOUBLE_EQ(a.track.large_step_db, 2.0);
    EXPECT_DOUBLE_EQ(a.track.small_step_db, 1.0);
}

TEST(AdaptiveListVariable, RefusesWordScoringSnrKeysBadListsAndCleanConditions) {
    try {
        adaptive_protocol(list_protocol("variable = \"bands\"\nprocedure = \"word\"\nlevels = [2, 1.5, 2, 99]\n"
                                        "start_level = 5\nstart_snr_db = 0\n",
                                        "clean"));
        FAIL() << "accepted";
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("adaptive.procedure: expected \"sentence\" with variable = \"bands\""), std::string::npos) << m;
        EXPECT_NE(m.find("study.toml:21:14: error: adaptive.levels[2]: expected a band count in [1, 64], got 1.5"),
                  std::string::npos)
            << m;
        EXPECT_NE(m.find("adaptive.levels[3]: expected levels in strictly ascending order"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.levels[4]: expected a band count in [1, 64], got 99"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.start_level: expected one of the levels (2), got 5"), std::string::npos) << m;
        EXPECT_NE(m.find("adaptive.start_snr_db: expected only with variable = \"snr\""), std::string::npos) << m;
        EXPECT_NE(m.find("condition \"av\" has audio = \"clean\""), std::string::npos) << m;
    }
    try {
        adaptive_protocol(list_protocol("levels = [1, 2]\n"));
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("adaptive.levels: expected only with variable = \"bands\" or \"cutoff\""),
                  std::string::npos)
            << e.what();
    }
    EXPECT_THROW(adaptive_protocol(list_protocol("variable = \"cutoff\"\nlevels = [16]\n")), InputError);
}
