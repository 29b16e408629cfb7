// The neural control models of the reference study (Beskow §4.4–4.5,
// Table 1, Fig. 4): four separate recurrent three-layer networks, each
// predicting one group of parameters from the 17 phonetic features of the
// current phone, presented frame-synchronously (60 fps by default) through a
// time-delay window of B frames behind and A frames ahead:
//
//     x_t = [f_{t−B}, …, f_t, …, f_{t+A}]                 (17·(A+B+1) inputs)
//     h_t = tanh(W x_t + Σ_{d=1..D} U_d h_{t−d} + b)       (D = 5 delays)
//     o_t = V h_t + c,   z_p = neutral_p + range_p · o_{t,p}
//
// with h_t = 0 for t < 0 and silence features for frames outside the
// phones (before, after, and in gaps). ANN 1 uses A = B = 15; ANN 2 (the
// low-latency model) A = 2, B = 28. Table 1 groups: occlusion (jaw rotation,
// upper lip raise, lower lip depression; 50 hidden), rounding (lip rounding,
// mouth corner stretch left/right; 50), protrusion (upper/lower lip
// retraction; 30), jaw (jaw thrust, jaw shift; 30).
//
// This header is the inference side: plain C++ (Eigen), no libtorch. The
// training side (backpropagation through time with libtorch) is in
// learn/include/avsi/learn/ann_training.h. Model file (kind "ann", read by load_model):
//
//     {"kind": "ann", "version": 1, "provenance": {…},
//      "config": {"fps": 60, "look_ahead": 2, "look_back": 28, "delays": 5},
//      "networks": [{"name": "occlusion", "params": ["jaw_rotation", …],
//                    "hidden": 50, "encoding": "base64-f32le",
//                    "W": "<base64>", "U": "…", "b": "…", "V": "…", "c": "…"}, …],
//      "training": {…free-form facts: corpus hash, epochs, errors, seconds…}}
//
// Weight blobs are row-major little-endian float32: W is hidden × inputs,
// U hidden × (delays · hidden) with column block d−1 multiplying h_{t−d},
// b hidden, V params × hidden, c params.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/synth/control_model.h"

namespace avsi::synth {

// The time-delay window and frame rate shared by all networks of a model.
struct AnnConfig {
    double fps = 60.0;
    int look_ahead = 15;   // A: future frames seen
    int look_back = 15;    // B: past frames seen
    int delays = 5;        // D: recurrent delays 1…D

    std::size_t window() const { return static_cast<std::size_t>(look_ahead + look_back + 1); }
    std::size_t inputs() const { return window() * feature_count; }
};

// ANN 1 (±15 frames) and ANN 2 (2 ahead, 28 behind).
AnnConfig ann1_config();
AnnConfig ann2_config();

// One network of Table 1: its name, parameters and hidden units.
struct AnnGroup {
    std::string name;
    std::vector<Param> params;
    int hidden = 50;
};

// The four groups of Table 1 in order: occlusion, rounding, protrusion, jaw.
const std::vector<AnnGroup>& ann_groups();

// Frame k's features (k = 0 … frames−1, frame k at time k / fps): those of
// the phone whose [start, end) holds k / fps, silence if none.
std::vector<FeatureVector> encode_frame_features(const PhoneSequence& phones, double fps, std::size_t frames);

// The window input of frame k: features of frames k−B … k+A in that order
// (oldest first), silence for frames outside [0, features.size()).
void window_input(std::span<const FeatureVector> features, std::ptrdiff_t k, const AnnConfig& config,
                  std::span<float> out);

// One trained network's weights (layout as in the file comment).
struct AnnNetwork {
    AnnGroup group;
    std::vector<float> W, U, b, V, c;

    // Throws InputError naming `what` unless every size matches `config`.
    void check_sizes(const AnnConfig& config, const std::string& what) const;
};

// Runs one network frame by frame; keeps the recurrent state.
class AnnRecurrentState {
public:
    AnnRecurrentState(const AnnNetwork& network, const AnnConfig& config);
    // Advances one frame with window input x; writes the group's outputs
    // (already mapped to parameter units) into `frame`.
    void step(std::span<const float> x, Frame& frame);

private:
    const AnnNetwork* m_net;
    int m_delays;
    std::vector<float> m_history;   // delays × hidden, row d−1 is h_{t−d}
    std::vector<float> m_pre;
    std::vector<float> m_h;
};

class AnnModel final : public ControlModel {
public:
    AnnModel(AnnConfig config, std::vector<AnnNetwork> networks);

    std::string_view kind() const override { return "ann"; }
    // Runs the networks at the model frame rate over the frames covering
    // the times, then interpolates linearly between frames.
    void evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                  std::vector<Frame>& out) const override;
    std::string to_json_text() const override;

    // The frames 0 … frames−1 at the model's frame rate (their look-ahead
    // reads the phones past the last frame). Parameters no network predicts
    // stay at their neutral value.
    std::vector<Frame> run_frames(const PhoneSequence& phones, std::size_t frames) const;

    const AnnConfig& config() const { return m_config; }
    const std::vector<AnnNetwork>& networks() const { return m_networks; }
    // Free-form training facts written under "training" in the file.
    std::string training_json;   // a JSON object as text, or empty

private:
    AnnConfig m_config;
    std::vector<AnnNetwork> m_networks;
};

// One streamed output frame.
struct StreamFrame {
    std::size_t index = 0;
    double time_s = 0.0;
    Frame values{};
};

// ANN streaming (§4.5): phones arrive in time order, as from a phoneme
// recogniser (a recogniser may report a phone in pieces, e.g. one segment per
// frame); frame k is computed as soon as the features of frame k + A are
// known, i.e. once the phones reach past (k + A) / fps. The output equals
// AnnModel::run_frames over the same phones.
class AnnStreamer {
public:
    explicit AnnStreamer(const AnnModel& model);

    // Adds the next phone. Throws InputError if it ends before it starts or
    // starts before the previous phone's end; a gap is silence.
    void push(const Phone& phone);
    // No more phones: frames after the last phone see silence; every frame
    // up to frame_count(last end) becomes ready.
    void finish();
    // The frames that became ready since the last call, in order.
    std::vector<StreamFrame> take_ready();
    // Frames whose features are known (k / fps < end of the pushed phones).
    std::size_t known_frames() const { return m_features.size(); }

private:
    void advance();

    const AnnModel* m_model;
    std::vector<AnnRecurrentState> m_states;
    std::vector<FeatureVector> m_features;   // per frame, known so far
    double m_known_until_s = 0.0;
    bool m_finished = false;
    std::size_t m_total_frames = 0;          // after finish
    std::size_t m_next = 0;                  // next frame to compute
    std::vector<float> m_x;
    std::vector<StreamFrame> m_ready;
};

}  // namespace avsi::synth
