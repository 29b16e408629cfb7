// The Cohen-Massaro model of coarticulation (Beskow §4.2, eq. 7–8): each
// segment i has, per articulatory parameter, a target T_i and a dominance
//
//     D_i(t) = α_i·exp(−θ_i·(τ_i − t)^c_i)   for t <  τ_i   (anticipatory)
//     D_i(t) = α_i·exp(−φ_i·(t − τ_i)^c_i)   for t >= τ_i   (carry-over)
//
// with τ_i the segment centre (s), θ, φ in s^−c; and the trajectory is the
// dominance-weighted mean of the targets, z(t) = Σ T_i D_i(t) / Σ D_i(t).
// Free parameters per phone and parameter: T, α, θ, φ; the exponent c per
// phone (as the issue specifies; the paper has c_i per segment of a phone).
// Silence segments take part like any phone, with their own (neutral)
// targets, so the face returns to rest in pauses and at utterance edges.
//
// Evaluation is linear in utterance length: for the frames in the Voronoi
// cell of segment j (the times nearer τ_j than any other centre) the sum is
// bounded below by L_j = min D_j over those frames, and every segment whose
// dominance is below δ_j = ε·L_j / (ΔT·N) at all of them is skipped (ΔT the
// spread of the targets, N the number of segments). The skipped segments
// change z by at most ΔT·Σ_skipped D / Σ_kept D < N·δ_j·ΔT / L_j = ε, so the
// result stays within ε of the full sum. Each segment's reach follows from
// solving α·exp(−θ r^c) = δ for r. Only at the frames within a kept
// segment's reach are dominances evaluated, as absolute values (all >= δ_j,
// so no underflow while δ_j >= e^−680; below that, per frame by the
// pointwise sum below, in the log domain shifted by the largest dominance).
// All parameters of a segment share τ and c, so |τ − t|^c is computed once
// per segment and frame (as exp(c·ln|τ − t|); directly for c = 1, 2) and
// exp(−θ·|τ − t|^c) once per distinct rate of the segment, over only the
// frames that rate's parameters reach (vectorised: glibc's libmvec, AVX2
// where the processor has it, see synth/src/cm_kernel.h; for c = 1 on
// uniform frames by an exact recurrence).
// Segments with c = 1 on uniformly spaced frames need no bound at all: for
// c = 1 a dominance factorises along time, so per parameter and distinct
// rate the sum over all such segments obeys a first-order recursion
// (A(t_f) = A(t_{f+1})·exp(−θ·h) + the segments passed), one multiply per
// frame and rate however far the tails reach; that is the exact full sum up
// to rounding (recursive_sums in synth/src/cm_bounded_sum.h). It is used
// unless some cell owner's dominance is below e^−600 (then the bounded path
// above). The steps are named functions in synth/src/cm_bounded_sum.h.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "avsi/synth/control_model.h"

namespace avsi::synth {

// One phone's Cohen-Massaro parameters for one articulatory parameter.
struct CohenMassaroParams {
    double target = 0.0;     // T, in the parameter's units
    double alpha = 1.0;      // α, peak dominance, > 0
    double theta_per_s = 30.0;  // θ, anticipatory rate (s^−c), > 0
    double phi_per_s = 30.0;    // φ, carry-over rate (s^−c), > 0
};

// One phone's table: c and the 10 parameters' (T, α, θ, φ).
struct CohenMassaroPhone {
    double c = 1.0;  // dominance exponent, > 0
    std::array<CohenMassaroParams, param_count> params{};
};

// One segment of an utterance, for one articulatory parameter: what eq. 7–8
// need. Also used by the MPEG-4 variant, the plots and the training gradient.
struct CmSegment {
    double tau_s = 0.0;  // centre (plus any offset)
    double target = 0.0;
    double alpha = 1.0;
    double theta_per_s = 30.0;
    double phi_per_s = 30.0;
    double c = 1.0;
};

// D_i(t) of eq. 7.
double dominance(const CmSegment& segment, double t_s);
// ln D_i(t), finite even where D_i(t) underflows.
double log_dominance(const CmSegment& segment, double t_s);

// Default bound for the skipped dominance: results within this of the full sum.
inline constexpr double cm_default_tolerance = 5e-10;

// What one segment contributes to z(t) at one time (eq. 7), as the
// pointwise evaluation (CmPointwiseSum) hands it on: enough to differentiate
// z (eq. 9–14, learn/src/training.cpp) without evaluating anything again.
struct CmTerm {
    std::uint32_t segment = 0;  // index into the segments
    bool before = false;        // t < τ_i: the anticipatory side (θ), else φ
    double distance_s = 0.0;    // x = |τ_i − t|
    double log_distance = 0.0;  // ln x (when x > 0 and asked for, or c_i ≠ 1)
    double distance_c = 0.0;    // x^c_i
    double weight = 0.0;        // D_i(t) / max_j D_j(t)
};

// By default the pointwise sum leaves out a segment whose dominance at t is
// below e^−40 of the largest there: all of them together move z by less
// than N·5e-18 of the target spread, far below double precision of the sum.
inline constexpr double cm_skip_log_ratio = 40.0;

// Eq. 7–8 at one time at a time, segment by segment: the one pointwise
// evaluation of the model, used for the full sum (the reference and
// tolerance 0), the bounded sum's log-domain cells, and training, which
// differentiates its terms. From the two segments bracketing t (the largest
// dominance so far, m), a segment at distance x can only reach
// ln D >= m − skip_log_ratio if ln α_max − rate_min·min(x^c_min, x^c_max)
// >= m − skip_log_ratio, which bounds x; the walk outward on each side stops
// there (recomputed when a farther segment raises m), so far segments are
// never evaluated (skip_log_ratio = ∞: every segment). Log domain, shifted
// by the largest dominance: never divides by zero. x^c is exp(c·ln x).
class CmPointwiseSum {
public:
    // segments non-empty, in ascending τ; they must outlive this object.
    explicit CmPointwiseSum(std::span<const CmSegment> segments, double skip_log_ratio = cm_skip_log_ratio);

    // z(t) of eq. 8; the contributing segments' terms in terms(), their
    // weights summing to weight_sum(). need_log_distance: also ln|τ − t|
    // for c = 1 segments (for ∂/∂c).
    double evaluate(double t_s, bool need_log_distance = false);
    const std::vector<CmTerm>& terms() const { return m_terms; }
    double weight_sum() const { return m_weight_sum; }

private:
    // Collects the contributing segments at t into m_terms; returns max ln D.
    double collect(double t, bool need_log_x);
    // The largest x with ln α_max − rate·min(x^c_min, x^c_max) >= m − skip_log_ratio.
    double max_distance(double m, double rate) const;

    std::span<const CmSegment> m_s;
    double m_skip_log_ratio;
    std::vector<double> m_log_alpha;
    double m_max_log_alpha;
    double m_min_theta;
    double m_min_phi;
    double m_min_c;
    double m_max_c = 0.0;
    std::vector<CmTerm> m_terms;
    std::vector<double> m_ratio;
    double m_weight_sum = 0.0;
};

// z(t) of eq. 8 at each time by the full O(N·F) sum (the reference): the
// pointwise sum keeping every segment.
// segments non-empty, any order; times any order; out.size() == times.size().
void cohen_massaro_full(std::span<const CmSegment> segments, std::span<const double> times_s,
                        std::span<double> out);

// z(t) of eq. 8 in O(N + F) (per segment, a bounded number of neighbours):
// within `tolerance` of cohen_massaro_full. times must be ascending.
void cohen_massaro_bounded(std::span<const CmSegment> segments, std::span<const double> times_s,
                           std::span<double> out, double tolerance = cm_default_tolerance);

// z(t) of eq. 8 for all parameters at once (segments[p] = parameter p's
// segments), each within `tolerance` of cohen_massaro_full. Where every
// segment has the same centre and c for all parameters (as the models make
// them), |τ − t|^c is computed once per segment and frame and the ten
// dominances together; otherwise parameter by parameter. out is resized to
// times.size(); times must be ascending; tolerance 0 means the full sum.
void cohen_massaro_bounded_all(const std::array<std::vector<CmSegment>, param_count>& segments,
                               std::span<const double> times_s, std::vector<Frame>& out,
                               double tolerance = cm_default_tolerance);

// A model whose trajectories are eq. 8 over per-segment dominance functions
// (Cohen-Massaro and its MPEG-4 variant); evaluation by the bounded sum.
class DominanceModel : public ControlModel {
public:
    // The segments of an utterance for every parameter, in utterance order.
    // Throws InputError for a phone the model has no entry for.
    virtual std::array<std::vector<CmSegment>, param_count> segments_all(const PhoneSequence& phones) const = 0;
    // The segments for one parameter.
    std::vector<CmSegment> segments(const PhoneSequence& phones, Param param) const;

    void evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                  std::vector<Frame>& out) const override;

    // Evaluation tolerance (see the file comment); 0 means the full sum.
    double tolerance = cm_default_tolerance;
};

// Phone-keyed Cohen-Massaro tables (kind "cohen-massaro").
class CohenMassaroModel : public DominanceModel {
public:
    using Table = std::map<std::string, CohenMassaroPhone, std::less<>>;

    explicit CohenMassaroModel(Table phones) : m_phones(std::move(phones)) {}

    std::string_view kind() const override { return "cohen-massaro"; }
    std::string to_json_text() const override;
    // τ = segment centre; T, α, θ, φ, c from the phone's entry.
    std::array<std::vector<CmSegment>, param_count> segments_all(const PhoneSequence& phones) const override;

    const Table& phones() const { return m_phones; }
    Table& phones() { return m_phones; }

private:
    Table m_phones;
};

}  // namespace avsi::synth
