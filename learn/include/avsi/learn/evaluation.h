// Objective evaluation of control models against measured trajectories
// (Beskow §5, Table 2 and Fig. 5): per parameter, over the frames of a test
// set, the RMSE as a percentage of the parameter's full range
// (parameters.h) and the Pearson product-moment correlation ρ between
// target y and prediction z, pooled over all test utterances; then averaged
// over the parameters the corpus has. Three frame subsets: all non-silence
// frames, vowel frames and consonant frames, each frame labelled by the
// phone its time falls in. Missing target values (NaN) are left out.
//
// Phonetic columns (given an articulation function: what the face shows for
// a trajectory, per frame, measured on a head — the CLI passes the stimuli
// module's ArticulationMeter on the built-in head): per model, the closure
// attainment rate of the bilabials and the contact rate of the labiodentals
// (synth/articulation_check.h: a sampled frame of each segment closed /
// within reach), and the mean absolute error at those segments' frames of
// the lip aperture (/p b m/) and of the lower lip's distance to the upper
// incisors (/f v/) against the same measures of the corpus track; and the
// corpus track's own rates (the "reference" row), so a reader sees that the
// data closes its bilabials.
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
#include "avsi/synth/articulation_check.h"
#include "avsi/synth/closure_constraint.h"

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

// A /p b m/ or /f v/ segment that came least close to closure or contact.
struct PhoneticSegment {
    std::string utterance;
    std::string phone;
    double start_s = 0.0, end_s = 0.0;
    double distance_mm = 0.0;  // aperture (bilabial) or lower lip to upper incisors (labiodental) at its best frame
};

// The phonetic columns of one model (or of the reference data).
struct PhoneticScores {
    std::size_t bilabials = 0, bilabials_closed = 0;
    std::size_t labiodentals = 0, labiodentals_reached = 0;
    double aperture_error_mm = 0.0;        // mean |model − reference| over /p b m/ frames; NaN when none
    double lip_to_incisors_error_mm = 0.0; // the same over /f v/ frames
    std::size_t utterances = 0;            // utterances measured (a track with missing values is skipped)
    // The bilabials left furthest open and the labiodentals furthest from
    // contact (up to worst_segments_kept each, worst first).
    std::vector<PhoneticSegment> worst_bilabials, worst_labiodentals;
    static constexpr std::size_t worst_segments_kept = 5;

    double closure_rate() const { return bilabials ? double(bilabials_closed) / double(bilabials) : 0.0; }
    double contact_rate() const { return labiodentals ? double(labiodentals_reached) / double(labiodentals) : 0.0; }
};

// What the face shows for a trajectory: the articulation measures of each frame.
using ArticulationFunction = std::function<std::vector<synth::ArticulationMeasures>(const Trajectory&)>;

struct ModelScores {
    std::string name;
    std::optional<PhoneticScores> phonetic;  // with an articulation function
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

// Scores each predictor on the utterances (predictions at the tracks' frame
// times); with `articulation`, also the phonetic columns.
std::vector<ModelScores> evaluate_predictors(const std::vector<CorpusUtterance>& utterances,
                                             const std::vector<NamedPredictor>& predictors,
                                             const ArticulationFunction& articulation = {});

// The phonetic columns of the corpus tracks themselves (errors are 0).
PhoneticScores reference_phonetic_scores(const std::vector<CorpusUtterance>& utterances,
                                         const ArticulationFunction& articulation);

// The phonetic table (Markdown) and CSV
// (model,bilabials,bilabials_closed,closure_rate,labiodentals,labiodentals_reached,contact_rate,
//  aperture_error_mm,lip_to_incisors_error_mm), the reference data first.
std::string phonetic_markdown(const PhoneticScores& reference, const std::vector<ModelScores>& scores);
// Per model, its worst bilabial and labiodental segments (Markdown).
std::string worst_segments_markdown(const std::vector<ModelScores>& scores);
std::string phonetic_csv(const PhoneticScores& reference, const std::vector<ModelScores>& scores);

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
    // What the face shows (phonetic columns, <out>_phonetic.csv); empty: none.
    ArticulationFunction articulation;
    std::string articulation_head;               // described in the caption
    // Also score each model with the closure constraint (synth/closure_constraint.h), as
    // "<name>+hold"; needs the head's lip tasks.
    bool closure_hold = false;
    synth::LipTaskFunction lip_tasks;
};

struct EvaluationResult {
    std::vector<ModelScores> scores;
    std::optional<PhoneticScores> reference;  // with an articulation function
    std::string markdown;     // what <out>.md holds
    std::size_t utterances = 0;
};

// `avsi evaluate`: loads the corpus and the models, scores them on the chosen
// split, writes the CSV, Markdown and SVG plot. Throws InputError for bad input.
EvaluationResult run_evaluation(const EvaluationSettings& settings);

}  // namespace avsi::learn
