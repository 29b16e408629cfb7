// Training the ANN control models (Beskow §4.4–4.5; model in ann.h) with
// libtorch: backpropagation through time over whole utterances (the
// recurrence unrolled over every frame, autograd for the gradients), Adam on
// mini-batches of utterances padded to equal length, the squared error of
// the range-normalised parameters ((y − neutral)/range) summed over present
// values only — missing parameters and NaN frames are masked out of the loss.
// Optionally the utterances are cut into overlapping chunks with a warm-up
// (truncated BPTT, see AnnTrainingSettings::chunk_frames) — the defaults in
// protocols/models were trained that way for speed.
// Early stopping (§4.4: "training was terminated when the error over the
// test set stopped decreasing"): after every epoch the held-out error is
// computed; a network stops after `patience` epochs without a new minimum
// and keeps the weights of its minimum. The held-out set is the corpus' test
// split, as in the study and in training.h. Each network trains on its own.
//
// Reproducible: torch::manual_seed(seed) before each network's
// initialisation and batch shuffling, deterministic algorithms, and a fixed
// intra-op thread count (default 1), so the same seed and data give the same
// weights bit for bit.
//
// The look-ahead sweep (§4.5, Fig. 4) trains the occlusion network with a
// total window of 31 frames for each look-ahead A (B = 30 − A) and writes the
// test error against A as CSV and an SVG plot.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "avsi/learn/articulatory_corpus.h"
#include "avsi/synth/ann.h"

namespace avsi::learn {

// learn builds on synth's parameters, trajectories and control models.
using namespace avsi::synth;

struct AnnTrainingSettings {
    AnnConfig config = ann1_config();
    std::vector<AnnGroup> groups = ann_groups();   // the networks to train
    int max_epochs = 200;       // the study: ~200 iterations
    int patience = 10;          // epochs without a held-out minimum before stopping
    int batch_utterances = 32;  // utterances (or chunks) per Adam step
    // Truncated BPTT (the default, 1 s chunks): 0 trains on whole utterances; otherwise on chunks of
    // this many frames, each preceded by `warmup_frames` frames that run the
    // recurrence (the gradient flows through them) but are left out of the
    // loss, so the chunk starts from a realistic hidden state.
    int chunk_frames = 60;
    int warmup_frames = 30;
    double learning_rate = 3e-3;
    double max_seconds = 0.0;   // per network wall-clock budget (0: none); stops like early stopping
    std::uint64_t seed = 2004;
    int threads = 1;            // torch intra-op threads (results depend on it)
};

struct AnnNetworkReport {
    std::string name;
    int epochs = 0;                 // epochs run
    int best_epoch = 0;             // 1-based epoch whose weights were kept
    double train_rmse_percent = 0;  // RMS over the group's present values, % of range, at best_epoch
    double test_rmse_percent = 0;
    double seconds = 0;
    std::vector<double> test_curve; // held-out RMSE % per epoch
};

struct AnnTrainingReport {
    std::unique_ptr<AnnModel> model;
    std::vector<AnnNetworkReport> networks;
    double seconds = 0;
};

// Trains the settings' networks on `train`, early-stopping on `test` (if
// `test` is empty, on `train`). Throws InputError if there is nothing to
// train on or a group's parameters are missing from every utterance.
AnnTrainingReport train_ann(const AnnTrainingSettings& settings, const std::vector<CorpusUtterance>& train,
                            const std::vector<CorpusUtterance>& test);

// One point of Fig. 4.
struct LookaheadPoint {
    int look_ahead = 0;
    int look_back = 0;
    int epochs = 0;
    double train_rmse_percent = 0;
    double test_rmse_percent = 0;
    double seconds = 0;
};

// Trains the occlusion network for each look-ahead in [first, last] with
// look_back = window − 1 − look_ahead (window 31 in the study).
std::vector<LookaheadPoint> sweep_lookahead(const AnnTrainingSettings& settings, int first, int last, int window,
                                            const std::vector<CorpusUtterance>& train,
                                            const std::vector<CorpusUtterance>& test);

// Writes the sweep as CSV (look_ahead,look_back,epochs,train_rmse_percent,
// test_rmse_percent,seconds) and an SVG plot of test error against look-ahead.
void write_lookahead_csv(const std::filesystem::path& path, const std::vector<LookaheadPoint>& points);
void write_lookahead_svg(const std::filesystem::path& path, const std::vector<LookaheadPoint>& points);

struct AnnCommandSettings {
    std::string model = "ann";               // ann | ann1 (A = B = 15) | ann2 (A = 2, B = 28)
    std::optional<int> look_ahead;           // overrides the preset
    std::optional<int> look_back;
    std::string sweep;                       // "first..last": run the sweep instead
    int sweep_window = 31;
    AnnTrainingSettings training;
    std::filesystem::path corpus;
    std::filesystem::path out;               // model .json; for a sweep a folder
    std::optional<std::uint64_t> split_seed;
    std::optional<double> test_fraction;
};

// `avsi train --model ann…`: loads and splits the corpus, trains, writes the
// model (provenance: corpus path and hash, split, epochs, errors, time) or,
// with a sweep, <out>/lookahead.csv and <out>/lookahead.svg.
void run_ann_command(const AnnCommandSettings& settings);

// Parses "a..b" (or a single "a") into an inclusive range; throws UsageError.
std::pair<int, int> parse_lookahead_range(const std::string& text);

}  // namespace avsi::learn
