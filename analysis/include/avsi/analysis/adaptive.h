// Adaptive speech reception thresholds (SRT): the level rules of an adaptive
// track, the SRT estimates, the maximum-likelihood fit of the psychometric
// function, and simulated listeners for planning. Pure computation: the lab
// runner drives a track trial by trial, the analysis replays stored tracks,
// `avsi simulate-srt` runs them against simulated listeners.
//
// Two procedures (protocol [adaptive] procedure = "sentence" | "word"):
//   * sentence scoring, 1-up/1-down on "all keywords correct" (MacLeod &
//     Summerfield 1990; HINT, Nilsson, Soli & Sullivan 1994): after sentence k
//     the level goes down by the step if every keyword was correct, up
//     otherwise; the step is large_step_db after sentences 1..large_steps,
//     small_step_db after. With repeat_first, the first sentence is presented
//     again, large_step_db higher each time, until it is correct. SRT = mean of
//     the levels of sentences srt_from..N (the last presentation of a repeated
//     sentence), plus the level the next sentence would get when
//     srt_include_next (HINT). This converges on the level where the whole
//     sentence is right half the time — for a listener whose keywords are
//     independent with word probability p(L), where p(L)^keywords = 0.5.
//   * word scoring, Brand & Kollmeier (2002): after each sentence
//       ΔL = −f(i) · (prop_correct − target) / slope_per_db,
//       f(i) = max(f_min, f_start · f_ratio^(−i)),
//     i = the number of reversals of the track so far (a reversal: a step of
//     the other sign than the last non-zero step). SRT from the mean of the
//     levels from sentence srt_from on, or from the maximum-likelihood fit of
//     a logistic psychometric function to every keyword of the track.
// Levels are bounded to [min_db, max_db]; a step that the bound shortens is
// recorded (TrackStep::at_bound), never hidden.
//
// Psychometric function (Brand & Kollmeier's form, slope at the midpoint),
// with an upper asymptote c (the ceiling, 1 − lapse rate; open-set keywords
// have no guess rate):
//   p(L) = c / (1 + exp(−4·s·(L − L50)))
// with s the slope in proportion per dB at L50 of the underlying logistic;
// the level for another target t < c is L_t = L50 + logit(t/c) / (4·s). A
// target at or above the ceiling has no level: a track aiming at it climbs to
// its upper bound (the reference study's 3-band audio-only condition reached
// 62.7 % of keywords in quiet, below the 79 % per keyword a 3-keyword
// sentence track aims at).
//
// Convergence: a track whose level hit a bound from sentence srt_from on, or
// that reversed fewer than min_reversals times, has not converged
// (track_convergence); the SRT analysis keeps such tracks out of the ANOVA and
// the visual benefit unless told otherwise.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <filesystem>

#include "avsi/core/adaptive_protocol.h"
#include "avsi/core/config.h"
#include "avsi/core/rng.h"
#include "avsi/core/shards.h"

namespace avsi {
struct Protocol;
}

namespace avsi::analysis {

// The protocol's [adaptive] section and the track rules are core's
// (avsi/core/adaptive_protocol.h), beside the protocol; analysis reads them
// under these names too.
using avsi::AdaptiveProcedure;
using avsi::AdaptiveProtocol;
using avsi::AdaptiveVariable;
using avsi::LevelRule;
using avsi::MaskerStage;
using avsi::SrtEstimator;
using avsi::TrackOrder;
using avsi::TrackSettings;
using avsi::adaptive_protocol;
using avsi::masker_description;
using avsi::to_string;

// One presentation of a track and the step it caused.
struct TrackStep {
    int presentation = 0;   // 1-based, repeats included
    int sentence = 0;       // 1-based; repeats of the first sentence share it
    int attempt = 1;        // presentation of this sentence (repeat_first)
    double level_db = 0.0;
    int keywords = 0;
    int correct = 0;
    bool sentence_correct = false;  // every keyword correct
    double step_db = 0.0;           // next_level_db − level_db
    double next_level_db = 0.0;
    bool reversal = false;          // this step reverses the track's direction
    int reversals = 0;              // reversals up to and including this step
    bool repeat = false;            // the next presentation repeats this sentence
    bool at_bound = false;          // the bound shortened this step
};

// An adaptive track: the level of the next presentation from the scored
// responses so far. Replaying the same scores gives the same levels (the
// runner resumes a track this way).
class AdaptiveTrack {
public:
    // Throws InputError (field "adaptive") for settings outside their ranges.
    explicit AdaptiveTrack(TrackSettings settings);

    // Level of the next presentation.
    double level_db() const { return m_level_db; }
    // Whether the next presentation repeats the last sentence (first-sentence rule).
    bool repeating() const { return m_repeat; }
    // Sentences completed (a repeated sentence counts once, when it ends).
    int sentences() const;
    int reversals() const { return m_reversals; }
    const std::vector<TrackStep>& steps() const { return m_steps; }
    const TrackSettings& settings() const { return m_settings; }

    // Scores the presentation at level_db(): `correct` of `keywords`
    // (keywords ≥ 1, 0 ≤ correct ≤ keywords) and steps. Returns the step.
    const TrackStep& record(int keywords, int correct);

private:
    TrackSettings m_settings;
    double m_level_db = 0.0;
    bool m_repeat = false;
    int m_reversals = 0;
    int m_last_direction = 0;  // sign of the last non-zero step
    std::vector<TrackStep> m_steps;
};

// Checks the settings; every problem is reported at once (InputError, field "adaptive.<key>").
void validate(const TrackSettings& settings, const std::string& source = "adaptive");

// Brand & Kollmeier's step factor after i reversals.
double bk_step_factor(const TrackSettings& settings, int reversals);

// The levels an SRT averages: the last presentation of each sentence from
// srt_from on (and the next level when srt_include_next).
std::vector<double> srt_levels(const TrackSettings& settings, const std::vector<TrackStep>& steps);

// One point of a psychometric function: `correct` of `trials` at a level.
struct PsychometricPoint {
    double level_db = 0.0;
    int trials = 0;
    int correct = 0;
};

// A maximum-likelihood fit of p(L) = c/(1 + exp(−4 s (L − L50))), c given.
struct PsychometricFit {
    double ceiling = 1.0;      // c, the upper asymptote (fixed, not fitted)
    bool converged = false;
    std::string note;          // why not, when not converged
    double l50_db = 0.0;
    double slope_per_db = 0.0; // s (fixed when slope_fixed)
    bool slope_fixed = false;
    double se_l50_db = 0.0;    // from the inverse Fisher information (delta method)
    double se_slope = 0.0;     // 0 when fixed
    double log_likelihood = 0.0;
    int points = 0;
    int trials = 0;
    int iterations = 0;

    // p(level) of the fitted function.
    double p(double level_db) const;
    // The level where p = target (0 < target < ceiling; NaN at or above the ceiling).
    double level_at(double target) const;
    // Its standard error (delta method; slope's uncertainty included when free).
    double se_level_at(double target) const;
    double cov_a_b = 0.0, var_a = 0.0, var_b = 0.0;  // of the logit intercept a and slope b = 4s
};

// Binomial maximum likelihood (Fisher scoring with step halving on
// p = c·logistic(a + b·L); with c = 1 this is Newton–Raphson on the logistic
// regression). With `fixed_slope_per_db` only L50 is fitted; `ceiling` c in
// (0, 1] is given (a pilot's, or 1). Data without a crossing (every trial
// right, every trial wrong, or a perfect separation) give converged = false
// and a note: there is no finite estimate.
PsychometricFit fit_psychometric(const std::vector<PsychometricPoint>& points,
                                 std::optional<double> fixed_slope_per_db = std::nullopt, double ceiling = 1.0);

// The keywords of a track as psychometric points (one per presentation).
std::vector<PsychometricPoint> track_points(const std::vector<TrackStep>& steps);

// An SRT estimate of one track.
struct SrtEstimate {
    bool valid = false;
    std::string note;        // why not valid
    double srt_db = 0.0;
    double se_db = 0.0;      // mean: SD/sqrt(n) of the averaged levels (they are correlated, so it is
                             // optimistic); ML: from the Fisher information
    int levels = 0;          // levels averaged (mean estimator)
    SrtEstimator estimator = SrtEstimator::MeanOfLevels;
    std::optional<PsychometricFit> fit;  // ML estimator
};

// The track's SRT by the settings' estimator (sentence tracks: the mean of levels).
SrtEstimate estimate_srt(const TrackSettings& settings, const std::vector<TrackStep>& steps);
// The track's SRT by a given estimator. ML on a sentence track fits the words
// and reports the level where the sentence (all `keywords` independent) is
// right half the time: p^k = 0.5.
// `ceiling` is the upper asymptote of the ML fit.
SrtEstimate estimate_srt(const TrackSettings& settings, const std::vector<TrackStep>& steps,
                         SrtEstimator estimator, double ceiling = 1.0);

// The level a procedure converges on for a listener whose keywords are each
// right with p(L) (logistic, l50_db, slope_per_db): for word tracks the level
// where p = target; for sentence tracks where p^keywords = 0.5.
double procedure_threshold_db(const TrackSettings& settings, double l50_db, double slope_per_db, int keywords);

// The per-keyword proportion a procedure tracks: its target (word scoring), or
// 0.5^(1/keywords) (sentence scoring: every keyword right half the time).
double tracked_proportion(const TrackSettings& settings, int keywords);

// A simulated listener: each keyword independently right with
// p(L) = ceiling·logistic(4·slope_per_db·(L − l50_db)).
struct SimulatedListener {
    double l50_db = -6.0;
    double slope_per_db = 0.15;
    int keywords = 3;
    double ceiling = 1.0;  // upper asymptote (1 − lapse rate), in (0, 1]
};

// The listener's keyword probability at a level.
double listener_p(const SimulatedListener& listener, double level_db);
// The level the procedure converges on for this listener (ceiling included);
// nullopt when the tracked proportion is at or above the ceiling.
std::optional<double> procedure_threshold_db(const TrackSettings& settings, const SimulatedListener& listener);

// Whether a track converged: its level did not hit a bound from sentence
// srt_from on (TrackStep::at_bound, or a presentation at the bound), and it
// reversed at least min_reversals times.
struct TrackConvergence {
    bool converged = true;
    bool at_bound = false;
    int reversals = 0;
    std::string reason;  // "" when converged, e.g. "at the upper bound (30 dB) from sentence 7"
};
TrackConvergence track_convergence(const TrackSettings& settings, const std::vector<TrackStep>& steps);

// `avsi simulate-srt`: tracks of `sentences` sentences against simulated
// listeners, for each sentence count.
struct SrtSimulationSettings {
    TrackSettings track;
    SimulatedListener listener;
    std::vector<int> sentence_counts = {10, 15, 20, 25, 30};
    int listeners = 1000;
    std::uint64_t seed = 1;
    double start_offset_sd_db = 0.0;  // the start level varies around track.start_db by N(0, sd²)
    bool include_unconverged = false;  // keep tracks that hit a bound or did not reverse (else: counted, left out)
};

// Bias and spread of one estimator at one track length.
struct SrtSimulationRow {
    int sentences = 0;
    std::string estimator;      // "mean" or "ml"
    double true_db = 0.0;       // procedure_threshold_db (what the estimate targets); NaN: above the ceiling
    int estimates = 0;          // listeners with a valid estimate (unconverged tracks left out unless included)
    int unconverged = 0;        // tracks flagged by track_convergence
    double mean_db = 0.0;
    double bias_db = 0.0;       // mean − true
    double sd_db = 0.0;         // spread of the estimates across listeners
    double rmse_db = 0.0;
    double mean_presentations = 0.0;  // repeats of the first sentence included
};

struct SrtSimulationResult {
    SrtSimulationSettings settings;
    std::vector<SrtSimulationRow> rows;
};

// Runs the simulation (deterministic for a seed). Throws InputError for bad settings.
SrtSimulationResult simulate_srt(const SrtSimulationSettings& settings);
// A cluster run (docs/cluster.md): shard K of N simulates, for every track
// length, its contiguous share of the listeners (shard_range), each from the
// seed it has in the whole run, and writes their tracks' outcomes to
// <out_dir>/srt_simulation.shard-K-of-N.csv. Validates as simulate_srt.
void simulate_srt_shard(const SrtSimulationSettings& settings, ShardSpec shard, const std::filesystem::path& out_dir);
// The merge: the shard files in `out_dir` summarised into the result
// simulate_srt(settings) gives, number for number; InputError naming a
// shard that is missing, stale, foreign, claims another's listeners or is
// cut short.
SrtSimulationResult merge_srt_shards(const SrtSimulationSettings& settings, const std::filesystem::path& out_dir);
// A plain-text table headed "SRT by simulation".
std::string srt_simulation_table(const SrtSimulationResult& result);
// srt_simulation.csv and srt_simulation.png (SD and bias by sentence count) into `out_dir`.
void write_srt_simulation(const std::filesystem::path& out_dir, const SrtSimulationResult& result);

// One simulated presentation: `keywords` Bernoulli(p(level)) draws.
int simulate_response(const SimulatedListener& listener, double level_db, Rng& rng);

// The steps of a track with every level (level, next level, step) in the
// variable's units (AdaptiveProtocol::value_of).
std::vector<TrackStep> in_units(const AdaptiveProtocol& adaptive, const std::vector<TrackStep>& steps);

// Design-time problems of an adaptive protocol: each condition whose ceiling
// is at or below the per-keyword proportion the track aims at (`keywords`
// keywords per sentence), so its track cannot converge and climbs to the bound.
std::vector<std::string> adaptive_design_warnings(const AdaptiveProtocol& adaptive, int keywords);

}  // namespace avsi::analysis
