// Objective evaluation of control models against measured trajectories
// (Beskow §5, Table 2 and Fig. 5): per parameter, over the frames of a test
// set, the RMSE as a percentage of the parameter's full range
// (parameters.h) and the Pearson product-moment correlation ρ between
// target y and prediction z, pooled over all test utterances; then averaged
// over the parameters the corpus has. Three frame subsets: all non-silence
// frames, vowel frames and consonant frames, each frame labelled by the
// phone its time falls in. Missing target values (NaN) are left out.
//
// Usage:
//     EvaluationAccumulator acc;
//     for (each test utterance) acc.add(phones, target_track, predicted_frames);
//     ModelScores s = acc.scores("cohen-massaro");
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/learn/articulatory_corpus.h"

namespace avsi::learn {

enum class FrameSubset { AllNonSilence = 0, Vowels, Consonants, Count };
inline constexpr std::size_t subset_count = static_cast<std::size_t>(FrameSubset::Count);
// "all non-silence", "vowels", "consonants".
std::string_view subset_name(FrameSubset subset);

struct Score {
    double rmse_percent = 0.0;   // RMSE / full range × 100; NaN when no frames
    double pearson = 0.0;        // NaN when either side is constant
    std::size_t frames = 0;
};

struct ModelScores {
    std::string name;
    // [subset][parameter]; frames == 0 for parameters the corpus lacks.
    std::array<std::array<Score, param_count>, subset_count> per_param{};
    // [subset]: the mean over parameters with frames (ρ over those where it is defined).
    std::array<Score, subset_count> mean{};
};

// Sums for RMSE and Pearson ρ, per subset and parameter.
class EvaluationAccumulator {
public:
    // Adds one utterance: `predicted[k]` is the model's frame at target.time_s(k).
    void add(const PhoneSequence& phones, const ParamTrack& target, const std::vector<Frame>& predicted);
    ModelScores scores(const std::string& name) const;

private:
    struct Sums {
        double n = 0, sy = 0, sz = 0, syy = 0, szz = 0, syz = 0, see = 0;
    };
    std::array<std::array<Sums, param_count>, subset_count> m_sums{};
};

// A model as evaluation sees it: the prediction at given times for phones.
using PredictFunction =
    std::function<void(const PhoneSequence& phones, std::span<const double> times_s, std::vector<Frame>& out)>;

struct NamedPredictor {
    std::string name;
    PredictFunction predict;
};

// Scores each predictor on the utterances (predictions at the tracks' frame times).
std::vector<ModelScores> evaluate_predictors(const std::vector<CorpusUtterance>& utterances,
                                             const std::vector<NamedPredictor>& predictors);

// Table 2 layout: a row per subset, RMSE (%) and ρ per model; then a
// per-parameter table per subset. Markdown and tidy CSV
// (model,subset,parameter,rmse_percent,pearson,frames; parameter "mean").
std::string scores_markdown(const std::vector<ModelScores>& scores, const std::string& caption);
std::string scores_csv(const std::vector<ModelScores>& scores);

// Fig. 5: an SVG (drawn with cairo) of one parameter for one utterance: the
// target track and each model's trajectory, phone labels along the time axis.
void write_trajectory_plot_svg(const std::filesystem::path& path, const CorpusUtterance& utterance, Param param,
                               const std::vector<std::pair<std::string, std::vector<double>>>& curves);

struct EvaluationSettings {
    std::filesystem::path corpus;
    std::vector<std::filesystem::path> models;   // model JSON files (control_model.h)
    std::filesystem::path out;                   // writes <out>.csv, <out>.md, <out>.svg
    std::string subset = "test";                 // test | train | all
    std::optional<std::uint64_t> split_seed;     // default: the corpus manifest's
    std::optional<double> test_fraction;
    std::string plot_utterance;                  // default: the first evaluated utterance
    std::string plot_param = "jaw_rotation";
};

struct EvaluationResult {
    std::vector<ModelScores> scores;
    std::string markdown;     // what <out>.md holds
    std::size_t utterances = 0;
};

// `avsi evaluate`: loads the corpus and the models, scores them on the chosen
// split, writes the CSV, Markdown and SVG plot. Throws InputError for bad input.
EvaluationResult run_evaluation(const EvaluationSettings& settings);

}  // namespace avsi::learn
