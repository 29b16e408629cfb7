// Training control models on measured articulation (Beskow §4): minimise
// the summed squared error e = (z − y)ᵀ(z − y) (eq. 5) per articulatory
// parameter with Levenberg-Marquardt (Ceres Solver) and analytic Jacobians,
// the per-segment derivatives summed over the segments of each phone class:
//
// - Cohen-Massaro (eq. 9–14): per phone key and parameter T, α, θ, φ, c;
//   from the terms of the model's pointwise sum (CmPointwiseSum in
//   cohen_massaro.h, eq. 7–8), in the log domain, ∂z/∂ψ_i = w_i·(∂ln D_i/∂ψ_i)·(T_i − z) with
//   w_i = D_i/ΣD (eq. 10), ∂z/∂T_i = w_i (eq. 9). Note eq. 14 as printed
//   lacks the minus sign: ∂D/∂c = −D·θ·(τ−t)^c·ln(τ−t) before the centre.
//   The model file keeps one c per phone (cohen_massaro.h), so with c free
//   training runs in two stages: all five free per parameter, then c set
//   to the median over the parameters and T, α, θ, φ refitted with it
//   fixed. By default c is fixed at 1 (TrainingSettings::min_c, max_c) and
//   only the second stage runs.
// - Öhman (eq. 18–20): vowel (and silence) targets a, consonant targets c and
//   coarticulation factors w_c ∈ [0, 1], differentiating the model's own
//   forward pass (ohman_value in ohman.h).
// - MPEG-4 Cohen-Massaro: the viseme targets per parameter and the shared
//   θ←, θ→ and peak offset t0 of the model's segments (mpeg4_segment) (one problem over all parameters, since they
//   are shared); α stays the ellipse-area normalisation of the viseme set.
//
// Bounds: targets within each parameter's range; α ∈ [1e-3, 1e3];
// θ, φ ∈ [min_rate_per_s, 1e4] (TrainingSettings); c ∈ [min_c, max_c]
// (default c = 1);
// w_c ∈ [0, 1]; t0 ∈ [−0.1, 0.1] s. The rate floor keeps dominances local:
// a dominance has fallen by e^−25 (below what the bounded sum keeps, see
// cohen_massaro.h) at the distance r with rate·r^c = 25, so a rate of 0.1
// would reach hundreds of seconds — no articulator anticipates a phone that
// far ahead — and make synthesis nearly O(N·F).
// Per-parameter problems run in parallel across cores. Early stopping
// (§4.1): after every iteration the held-out (test split) error is computed;
// training stops when it has not fallen for `patience` iterations and keeps
// the parameters with the lowest held-out error. The written model's
// provenance records the corpus and its hash, the split, the iterations and
// the train/test errors.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "avsi/learn/articulatory_corpus.h"
#include "avsi/synth/cohen_massaro.h"
#include "avsi/synth/control_model.h"

namespace avsi::learn {

// learn builds on synth's parameters, trajectories and control models.
using namespace avsi::synth;

struct TrainingSettings {
    std::string model = "cohen-massaro";   // cohen-massaro | ohman | mpeg4-cohen-massaro
    std::filesystem::path init_model;      // start point and untrained entries; default protocols/models/<model>.json
    int max_iterations = 50;               // per stage
    int patience = 3;                      // iterations without held-out improvement before stopping
    int threads = 0;                       // 0: all cores
    double function_tolerance = 1e-7;      // Ceres relative cost change to stop
    // Lower bound on the dominance rates θ, φ (s^−c; Cohen-Massaro and the
    // MPEG-4 variant's shared θ pair). At 10 a dominance with c = 1 has
    // fallen by e^−25 within 2.5 s (for c < 1 the tails are heavier; a floor
    // rising with 1/c cost 0.85 % of range in held-out RMSE, so is not used). Chosen on the reference corpus (186 train / 80
    // test, `bench_training --benchmark_filter=RateFloor`): held-out RMSE
    // 5.15 / 5.17 / 5.10 / 5.17 / 5.97 % of range (ρ 0.809 / 0.807 / 0.813 /
    // 0.818 / 0.787) for floors 0.1 / 2 / 5 / 10 / 20: up to 10 the floor
    // costs no accuracy (the differences are the optimiser's), 20 does.
    double min_rate_per_s = 10.0;
    // Range of the Cohen-Massaro dominance exponent c (per phone). When
    // min_c == max_c, c is fixed at that value and training has one stage
    // (T, α, θ, φ); otherwise two (see the file comment). Default c = 1,
    // chosen on the reference corpus (186 train / 80 test, rate floor 10;
    // synth/README.md): held-out RMSE 5.20 / 5.12 / 5.13 / 5.10 % of range
    // (ρ 0.817 / 0.819 / 0.810 / 0.812) for c in [0.5, 2.5] / [0.8, 2.5] /
    // [1, 2.5] / c = 1, so fixing c costs no accuracy, while synthesis of a
    // 60 s utterance takes 77 / 46 / 39 / 4.1 ms (c = 1 sums by recursion,
    // cohen_massaro.h) and training needs one stage instead of two.
    double min_c = 1.0;
    double max_c = 1.0;
};

struct TrainingReport {
    std::unique_ptr<ControlModel> model;
    int iterations = 0;                 // LM iterations summed over stages and parameters
    double train_rmse_percent = 0.0;    // mean over parameters, non-silence frames
    double test_rmse_percent = 0.0;
    double train_pearson = 0.0;
    double test_pearson = 0.0;
    double seconds = 0.0;
    // The parameters the training data measures (trained); the others keep
    // the initial model's values (a corpus without lateral data cannot train
    // jaw_shift or the mouth corners: docs/articulography.md).
    std::array<bool, param_count> trained{};
};

// The parameters with a measured value in some frame of the utterances' phones.
std::array<bool, param_count> measured_parameters(const std::vector<CorpusUtterance>& utterances);

// Trains a model of settings.model on `train`, early-stopping on `test`.
TrainingReport train_model(const TrainingSettings& settings, const std::vector<CorpusUtterance>& train,
                           const std::vector<CorpusUtterance>& test);

struct TrainCommandSettings {
    TrainingSettings training;
    std::filesystem::path corpus;
    std::filesystem::path out;
    SplitSettings split;
};

// `avsi train`: loads the corpus, splits it, trains, writes the model JSON
// (and for MPEG-4 CM its trained viseme set beside it, <out>.visemes.json).
TrainingReport run_training(const TrainCommandSettings& settings);

// ---- The analytic derivatives, exposed for gradient checks ----

// Per time k, the segments that contribute to z(t_k) and ∂z/∂(T, α, θ, φ,
// c, τ) of each, in compressed rows: entries row_start[k] .. row_start[k+1].
struct CmPartials {
    std::vector<std::size_t> row_start;
    std::vector<std::uint32_t> segment;
    std::vector<std::array<double, 6>> d;
};

// Eq. 8 at each time by the model's pointwise sum (CmPointwiseSum in
// cohen_massaro.h: log domain, segments below e^−40 of the largest left
// out) and, if `partials` is non-null, the partials of eq. 9–14 (and ∂/∂τ)
// of each contributing segment, from the sum's terms. Segments in ascending
// τ. need_dc false: ∂/∂c is left 0 (c held fixed; saves the ln|τ − t|).
void cohen_massaro_partials(std::span<const CmSegment> segments, std::span<const double> times_s,
                            std::vector<double>& z, CmPartials* partials, bool need_dc = true);

// One utterance of a phone-keyed model for one parameter: which key each
// segment uses, and the segment centres.
struct KeyedUtterance {
    std::vector<double> centres_s;
    std::vector<int> key;        // per segment
    std::vector<bool> anchor;    // Öhman: vowel or silence
    std::vector<double> times_s;
};

// Cohen-Massaro for one parameter: x holds 5 values per key (T, α, θ, φ, c);
// z at the times and J = ∂z/∂x (row-major, times × x.size()) if non-null.
void cohen_massaro_keyed(const KeyedUtterance& u, std::span<const double> x, std::vector<double>& z,
                         std::vector<double>* jacobian);

// Öhman for one parameter: x holds 2 values per key: anchors (a, unused),
// consonants (c, w_c). z by the model's forward pass (ohman_blends and
// ohman_value in ohman.h, eq. 16–17), J by eq. 18–20.
void ohman_keyed(const KeyedUtterance& u, std::span<const double> x, std::vector<double>& z,
                 std::vector<double>* jacobian);

}  // namespace avsi::learn
