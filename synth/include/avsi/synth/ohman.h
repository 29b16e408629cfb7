// Öhman's model of coarticulation as extended by Beskow (§4.3, eq. 15–17):
// a vowel track v(t) blended between successive vowel targets a_j,
//
//     v(t) = Σ_j a_j b_j(t) / Σ_j b_j(t)                          (eq. 17)
//
// onto which each consonant i pulls with coarticulation factor w_ci ∈ [0,1]:
//
//     z(t) = v(t) + Σ_{i ∈ C} w_ci k_i(t) (c_i − v(t))            (eq. 16)
//
// Blend functions are cubic (Hermite "smoothstep") on each side of their
// peak: b_j is 1 at vowel j's centre and 0 with zero slope at the centres of
// the neighbouring vowels; k_i is 1 at consonant i's centre and 0 with zero
// slope at the centres of the preceding and following segments. Both have
// zero slope at their peak too, so z is continuous with a continuous first
// derivative everywhere.
//
// Decisions (documented here and tested):
// - Silence (`sil`) is a vowel-like anchor of the vowel track with its own
//   (neutral) targets, so pauses and utterance edges return to rest rather
//   than holding the last vowel's shape, and a consonant next to a pause
//   blends toward rest.
// - Edges: before the first anchor's centre the vowel track is that anchor's
//   target (b = 1), after the last likewise; a first/last segment that is a
//   consonant keeps k = 1 from its centre to the utterance edge.
// - An utterance with no vowel or silence at all has v(t) = neutral.
// - Consecutive consonants pull independently; each one's k reaches 0 at its
//   neighbours' centres, so consonants never coarticulate with each other
//   (as in the paper).
//
// Model file (kind "ohman"):
//     {"kind": "ohman", "version": 1, "provenance": {…},
//      "vowels": {"AA": {"jaw_rotation": 0.9, …all 10…}, "sil": {…}, …},
//      "consonants": {"P": {"jaw_rotation": {"target": 0.1, "w": 0.9}, …}, …}}
#pragma once

#include <array>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "avsi/synth/control_model.h"

namespace avsi::synth {

struct OhmanConsonantParam {
    double target = 0.0;       // c_i
    double coarticulation_factor = 1.0;  // w_ci ∈ [0, 1]
};

using OhmanConsonant = std::array<OhmanConsonantParam, param_count>;

// The cubic blend half: 0 with zero slope at x = 0, 1 with zero slope at x = 1.
double smoothstep(double x);

// The vowel track's blend at t (eq. 17, cubic blends), shared by the model
// and its training: anchors `left` and `right` (indices into the anchor
// centres, −1 when unused) with weights summing to 1; before the first or
// after the last centre only that anchor, weight 1. No anchors: both −1.
struct VowelBlend {
    long left = -1;
    long right = -1;
    double w_left = 0.0;
    double w_right = 0.0;
};
VowelBlend ohman_vowel_blend(std::span<const double> anchor_centres, double t);

// k_i(t) of eq. 16 for the consonant at segment i (centres ascending): 1 at
// τ_i, 0 with zero slope at τ_{i−1} and τ_{i+1}, held at 1 toward an edge.
double ohman_consonant_blend(std::span<const double> centres, std::size_t i, double t);

// The blends at t over one utterance (eq. 16–17): the vowel track's anchors
// and weights, and the consonants with k_i(t) > 0 (only the segments whose
// centres bracket t can have one) with their k_i(t).
struct OhmanBlends {
    VowelBlend vowel;
    int consonants = 0;                      // entries used below
    std::array<std::size_t, 2> consonant{};  // segment indices
    std::array<double, 2> k{};               // k_i(t) > 0
};
// centres ascending (every segment), anchor_centres those of the anchors
// (vowels and silence), anchor[i] whether segment i is one.
OhmanBlends ohman_blends(std::span<const double> centres, std::span<const double> anchor_centres,
                         const std::vector<bool>& anchor, double t);

// One parameter at one time: z(t) of eq. 16, the vowel track v(t) of eq. 17
// and the consonants' total pull Σ w_ci·k_i(t) (what eq. 20 needs).
struct OhmanValue {
    double z = 0.0;
    double v = 0.0;
    double pull = 0.0;
};

// The vowel track of eq. 17 from the blends: anchor_target(j) is anchor j's
// target a_j; `neutral` where the utterance has no anchor.
template <class AnchorTarget>
double ohman_vowel_value(const VowelBlend& b, double neutral, const AnchorTarget& anchor_target) {
    if (b.left < 0) return neutral;
    if (b.right < 0) return anchor_target(b.left);
    return anchor_target(b.left) * b.w_left + anchor_target(b.right) * b.w_right;
}

// Eq. 16–17 for one parameter from the blends: the model's one forward pass,
// evaluated by OhmanModel and differentiated by training (eq. 18–20,
// learn/src/training.cpp). consonant(i) gives segment i's (c_i, w_ci).
template <class AnchorTarget, class Consonant>
OhmanValue ohman_value(const OhmanBlends& b, double neutral, const AnchorTarget& anchor_target,
                       const Consonant& consonant) {
    OhmanValue out;
    out.v = ohman_vowel_value(b.vowel, neutral, anchor_target);
    out.z = out.v;
    for (int e = 0; e < b.consonants; ++e) {
        const auto ue = static_cast<std::size_t>(e);
        const auto [c, w] = consonant(b.consonant[ue]);
        out.z += w * b.k[ue] * (c - out.v);
        out.pull += w * b.k[ue];
    }
    return out;
}

class OhmanModel : public ControlModel {
public:
    using VowelTable = std::map<std::string, Frame, std::less<>>;
    using ConsonantTable = std::map<std::string, OhmanConsonant, std::less<>>;

    OhmanModel(VowelTable vowels, ConsonantTable consonants)
        : m_vowels(std::move(vowels)), m_consonants(std::move(consonants)) {}

    std::string_view kind() const override { return "ohman"; }
    void evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                  std::vector<Frame>& out) const override;
    std::string to_json_text() const override;

    // The vowel track v(t) alone (eq. 17), for plots and the training gradient.
    void vowel_track(const PhoneSequence& phones, std::span<const double> times_s,
                     std::vector<Frame>& out) const;

    const VowelTable& vowels() const { return m_vowels; }
    const ConsonantTable& consonants() const { return m_consonants; }
    VowelTable& vowels() { return m_vowels; }
    ConsonantTable& consonants() { return m_consonants; }

private:
    VowelTable m_vowels;          // vowels and `sil`: targets a
    ConsonantTable m_consonants;  // consonants: targets c and factors w
};

}  // namespace avsi::synth
