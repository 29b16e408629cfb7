// The bounded Cohen-Massaro sum (Beskow §4.2, eq. 8; the bound is derived in
// cohen_massaro.h) as named steps, each tested (tests/synth/cm_bounded_sum_test.cpp):
//
//   cm_table              step 1: the segments sorted by centre, per parameter
//   uniform_step          whether the frames are uniformly spaced, and the step
//   cm_recursive_segments which segments the c = 1 recursions sum whole
//   recursive_sums        the c = 1 recursions (exact, O(F·R + N))
//   cm_cut_offs           pass 1: per cell the thresholds δ_j, per segment the
//                         hull of the frames where it may reach them
//   cm_rate_groups        per kept segment and side its distinct rates and reach
//   cm_accumulate_blocks  pass 2: each kept segment's dominances over its hull,
//                         in blocks of frames (vectorised, cm_kernel.h)
//   cm_log_domain_cells   the cells whose thresholds would underflow: by the
//                         model's pointwise sum (CmPointwiseSum) instead
//
// bounded_sum (cohen_massaro.cpp) is these in that order. All are templates
// over P, the number of parameters summed together (1, or param_count when
// the segments share centre and exponent over all parameters).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include "avsi/core/error.h"
#include "avsi/synth/cohen_massaro.h"
#include "cm_kernel.h"

namespace avsi::synth::detail {
// (File-local to each includer: cohen_massaro.cpp and the step tests. Internal
// linkage lets the compiler inline the steps into bounded_sum as it did when
// they were one function.)
namespace {

// |d|^c, with the common exponents exact and fast (pow as exp(c·ln|d|):
// relative error ~1e-15, far below what the tolerance needs).
inline double power(double a, double c) {
    if (c == 1.0) return a;
    if (c == 2.0) return a * a;
    return a > 0.0 ? std::exp(c * std::log(a)) : 0.0;
}

// Below this ln δ the absolute dominances could underflow; such a
// (cell, parameter) is summed in the log domain instead.
constexpr double min_log_delta = -680.0;

// One side (before or after the centre) of a segment: its distinct rates
// (θ before, φ after) and which of them each parameter uses, so that
// exp(−rate·|τ − t|^c) is computed once per distinct rate.
template <int P>
struct RateGroups {
    int count = 0;
    std::array<double, P> rate{};
    std::array<int, P> of_param{};
    // Per rate: how far from the centre (s) the rate's parameters can still
    // reach their thresholds; negative: nowhere.
    std::array<double, P> reach{};
};

// Flush-to-zero and denormals-are-zero for the current thread while alive
// (x86 SSE; elsewhere nothing): the recursions' decaying sums would
// otherwise crawl through subnormal numbers, dozens of times slower. What a
// flushed value loses is below 2.3e-308 per sum and step.
class FlushDenormals {
public:
#if defined(__SSE2__)
    FlushDenormals() : m_saved(_mm_getcsr()) { _mm_setcsr(m_saved | 0x8040u); }
    ~FlushDenormals() { _mm_setcsr(m_saved); }

private:
    unsigned m_saved;
#endif
};

// The exact sums over the segments with c = 1 on uniformly spaced frames
// t_f = t_0 + f·h. For c = 1 the dominance factorises along time: with
// A_r(t) = Σ_{τ_i > t} α_i·exp(−r·(τ_i − t)) over the segments of
// anticipatory rate r,
//     A_r(t_f) = A_r(t_{f+1})·exp(−r·h) + Σ_{t_f < τ_i <= t_{f+1}} α_i·exp(−r·(τ_i − t_f)),
// and likewise forward in time for the carry-over side (τ_i <= t, rate φ).
// So one multiply per frame and distinct rate replaces the exponential of
// every segment in reach: the whole sum, however far the tails reach, in
// O(F·R + N) for R distinct rates per parameter. (The same with T_i·α_i
// for the numerator.) Rounding: a product of up to F factors, relative
// error below F·2^−53 ≈ 4e-13 for an hour of frames at 60 fps.
// Adds into num/den (per frame the P parameters' sums) every `use[i]`
// segment's terms.
template <int P, class Mat>
void recursive_sums(std::span<const double> times, double step, const std::vector<double>& tau,
                    const std::vector<char>& use, const Mat& theta, const Mat& phi, const Mat& alpha,
                    const Mat& target_alpha, std::vector<std::array<double, static_cast<std::size_t>(P)>>& num,
                    std::vector<std::array<double, static_cast<std::size_t>(P)>>& den) {
    using Index = Eigen::Index;
    const std::size_t n = tau.size(), frames = times.size();
    FlushDenormals flush;
    for (int side = 0; side < 2; ++side) {
        const bool before = side == 0;
        const Mat& rates = before ? theta : phi;
        // Per parameter its distinct rates among the used segments; group g of
        // parameter p is row g, column p of the state arrays (unused cells
        // have decay 0 and stay 0).
        // (Distinct rates found by a small open-addressing table on the bits.)
        std::array<std::vector<double>, P> distinct;
        std::vector<std::array<std::uint32_t, static_cast<std::size_t>(P)>> group_of(n);
        std::size_t slots = 64;
        while (slots < 2 * n) slots *= 2;
        std::vector<std::uint32_t> table(slots);
        for (int p = 0; p < P; ++p) {
            auto& d = distinct[static_cast<std::size_t>(p)];
            std::fill(table.begin(), table.end(), 0u);  // 0: empty, else group + 1
            for (std::size_t i = 0; i < n; ++i) {
                if (!use[i]) continue;
                const double rate = rates(p, static_cast<Index>(i));
                std::uint64_t bits;
                std::memcpy(&bits, &rate, sizeof bits);
                std::size_t h = static_cast<std::size_t>((bits * 0x9E3779B97F4A7C15ull) >> 40) & (slots - 1);
                while (table[h] != 0 && d[table[h] - 1] != rate) h = (h + 1) & (slots - 1);
                if (table[h] == 0) {
                    d.push_back(rate);
                    table[h] = static_cast<std::uint32_t>(d.size());
                }
                group_of[i][static_cast<std::size_t>(p)] = table[h] - 1;
            }
        }
        std::size_t groups = 0;
        for (const auto& d : distinct) groups = std::max(groups, d.size());
        if (groups == 0) return;
        // Rows of `width` columns (P rounded up to whole vectors).
        constexpr std::size_t width = P == 1 ? 1 : (static_cast<std::size_t>(P) + 3) / 4 * 4;
        std::vector<double> decay(groups * width, 0.0), state_num(groups * width, 0.0),
            state_den(groups * width, 0.0);
        for (int p = 0; p < P; ++p)
            for (std::size_t g = 0; g < distinct[static_cast<std::size_t>(p)].size(); ++g)
                decay[g * width + static_cast<std::size_t>(p)] =
                    std::exp(-distinct[static_cast<std::size_t>(p)][g] * step);
        // Per frame: every sum decays by one step (not at the first frame) and
        // is added up per parameter (vectorised, cm_kernel.h); then the
        // segments passed are injected into their sums and the frame's totals.
        std::array<double, width> acc_num{}, acc_den{};
        auto decay_and_add = [&](bool decay_first) {
            detail::cm_decay_sum(state_num.data(), state_den.data(), decay.data(), groups, width, decay_first,
                                 acc_num.data(), acc_den.data());
        };
        auto inject = [&](std::size_t i, double t) {
            if (!use[i]) return;
            const auto col = static_cast<Index>(i);
            const double dist = before ? tau[i] - t : t - tau[i];
            for (int p = 0; p < P; ++p) {
                const auto up = static_cast<std::size_t>(p);
                const double e = std::exp(-rates(p, col) * dist);
                const std::size_t at = group_of[i][up] * width + up;
                const double en = target_alpha(p, col) * e, ed = alpha(p, col) * e;
                state_num[at] += en;
                state_den[at] += ed;
                acc_num[up] += en;
                acc_den[up] += ed;
            }
        };
        auto store = [&](std::size_t f) {
            for (std::size_t p = 0; p < static_cast<std::size_t>(P); ++p) {
                num[f][p] += acc_num[p];
                den[f][p] += acc_den[p];
            }
        };
        if (before) {
            // Backwards: at frame f the segments with τ > t_f not yet taken.
            std::size_t next = n;
            for (std::size_t f = frames; f-- > 0;) {
                decay_and_add(f + 1 < frames);
                while (next > 0 && tau[next - 1] > times[f]) inject(--next, times[f]);
                store(f);
            }
        } else {
            // Forwards: at frame f the segments with τ <= t_f not yet taken.
            std::size_t next = 0;
            for (std::size_t f = 0; f < frames; ++f) {
                decay_and_add(f > 0);
                while (next < n && tau[next] <= times[f]) inject(next++, times[f]);
                store(f);
            }
        }
    }
}
// The distance r >= 0 at which rate·r^c = y (y >= 0).
inline double reach_of(double y, double c) {
    return c == 1.0 ? y : c == 2.0 ? std::sqrt(y) : y > 0.0 ? std::exp(std::log(y) / c) : 0.0;
}

// Step 1: the segments sorted by centre as parameter × segment arrays, and
// per parameter the target spread and the extremes the bounds need.
template <int P>
struct CmTable {
    using Col = Eigen::Array<double, P, 1>;
    using Mat = Eigen::Array<double, P, Eigen::Dynamic>;
    std::size_t n = 0;
    std::vector<double> tau, c;  // per segment, shared by the parameters
    Mat target, log_alpha, theta, phi;
    Mat alpha, target_alpha, inv_theta, inv_phi;
    Col t_min, spread, max_log_alpha, min_rate;
    double c_min = 0.0, c_max = 0.0;
    // δ_j = ε·L_j/(ΔT·N): ln δ_j = ln L_j + ln_factor (never above ln L_j).
    Col ln_factor;

    // ln D_p(t) of segment i (eq. 7) for every parameter p.
    Col log_dominance(std::size_t i, double t) const {
        const double d = tau[i] - t;
        const double u = power(std::abs(d), c[i]);
        const auto col = static_cast<Eigen::Index>(i);
        if (d > 0.0) return log_alpha.col(col) - theta.col(col) * u;
        return log_alpha.col(col) - phi.col(col) * u;
    }
};

// Fills s (reusing its storage) from source(p, i), parameter p's segment i
// (any order), n >= 1.
template <int P, class Source>
void cm_table(std::size_t n, const Source& source, double tolerance, CmTable<P>& s) {
    using Index = Eigen::Index;
    s.n = n;
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return source(0, a).tau_s < source(0, b).tau_s; });
    s.tau.resize(n);
    s.c.resize(n);
    s.target.resize(P, static_cast<Index>(n));
    s.log_alpha.resize(P, static_cast<Index>(n));
    s.theta.resize(P, static_cast<Index>(n));
    s.phi.resize(P, static_cast<Index>(n));
    for (std::size_t i = 0; i < n; ++i) {
        s.tau[i] = source(0, order[i]).tau_s;
        s.c[i] = source(0, order[i]).c;
        for (int p = 0; p < P; ++p) {
            const CmSegment& g = source(static_cast<std::size_t>(p), order[i]);
            AVSI_ASSERT(g.alpha > 0.0 && g.theta_per_s > 0.0 && g.phi_per_s > 0.0 && g.c > 0.0);
            const auto col = static_cast<Index>(i);
            s.target(p, col) = g.target;
            s.log_alpha(p, col) = std::log(g.alpha);
            s.theta(p, col) = g.theta_per_s;
            s.phi(p, col) = g.phi_per_s;
        }
    }
    s.alpha = s.log_alpha.exp();
    s.target_alpha = s.target * s.alpha;
    s.inv_theta = s.theta.inverse();
    s.inv_phi = s.phi.inverse();
    s.t_min = s.target.rowwise().minCoeff();
    s.spread = s.target.rowwise().maxCoeff() - s.t_min;
    s.max_log_alpha = s.log_alpha.rowwise().maxCoeff();
    s.min_rate = s.theta.rowwise().minCoeff().min(s.phi.rowwise().minCoeff());
    s.c_min = *std::min_element(s.c.begin(), s.c.end());
    s.c_max = *std::max_element(s.c.begin(), s.c.end());
    for (int p = 0; p < P; ++p)
        s.ln_factor[p] = s.spread[p] > 0.0 ? std::min(0.0, std::log(tolerance) - std::log(s.spread[p]) -
                                                               std::log(static_cast<double>(n)))
                                           : 0.0;
}

// The same, returned.
template <int P, class Source>
CmTable<P> cm_table(std::size_t n, const Source& source, double tolerance) {
    CmTable<P> s;
    cm_table(n, source, tolerance, s);
    return s;
}

// The step h if the times are uniformly spaced, t_f = t_0 + f·h (at least
// two, within 1e-12 relative), else nothing: the c = 1 recursions and
// recurrences need it.
inline std::optional<double> uniform_step(std::span<const double> times) {
    const std::size_t frames = times.size();
    if (frames < 2) return std::nullopt;
    const double step = (times[frames - 1] - times[0]) / static_cast<double>(frames - 1);
    for (std::size_t f = 0; f < frames; ++f)
        if (!(std::abs(times[f] - (times[0] + step * static_cast<double>(f))) <= 1e-12 * (1.0 + std::abs(times[f]))))
            return std::nullopt;
    return step;
}

// Calls cell(j, k0, k1) for each segment j in turn whose Voronoi cell (the
// times before the midpoint to the next centre and not in an earlier cell)
// holds frames [k0, k1) (non-empty), starting at frame `first`, until the
// frames run out or cell returns false.
template <class Cell>
void for_each_cell(const std::vector<double>& tau, std::span<const double> times, std::size_t first, const Cell& cell) {
    const std::size_t n = tau.size(), frames = times.size();
    for (std::size_t j = 0, k = first; j < n && k < frames; ++j) {
        const double upper = j + 1 < n ? 0.5 * (tau[j] + tau[j + 1]) : std::numeric_limits<double>::infinity();
        const std::size_t k0 = k;
        while (k < frames && times[k] < upper) ++k;
        if (k == k0) continue;
        if (!cell(j, k0, k)) return;
    }
}

// Which segments recursive_sums sums whole (exact, no bound needed): those
// with c = 1, if the frames are uniform and no sum can underflow (every cell
// owner's dominance above e^−600 at its cell's frames, so the flushed
// subnormals are negligible, and no cell needing the log domain); else none.
template <int P>
std::vector<char> cm_recursive_segments(const CmTable<P>& s, std::span<const double> times, bool uniform) {
    std::vector<char> recursive(s.n, 0);
    if (!uniform) return recursive;
    bool any = false;
    for (std::size_t i = 0; i < s.n; ++i) any |= (recursive[i] = s.c[i] == 1.0) != 0;
    for_each_cell(s.tau, times, 0, [&](std::size_t j, std::size_t k0, std::size_t k1) {
        const typename CmTable<P>::Col ln_l = s.log_dominance(j, times[k0]).min(s.log_dominance(j, times[k1 - 1]));
        if ((s.spread > 0.0 && (ln_l <= -600.0 || ln_l + s.ln_factor <= min_log_delta)).any()) any = false;
        return any;
    });
    if (!any) std::fill(recursive.begin(), recursive.end(), 0);
    return recursive;
}

// Pass 1's result: per segment the hull of its kept frames, and the cells
// left to the log domain.
template <int P>
struct CmCutOffs {
    using Col = Eigen::Array<double, P, 1>;
    using Mat = Eigen::Array<double, P, Eigen::Dynamic>;
    static constexpr std::size_t none = std::numeric_limits<std::size_t>::max();
    std::vector<std::size_t> hull_lo, hull_hi;  // frames [lo, hi); lo == none: not kept
    // Per kept segment and parameter the lowest threshold ln δ_p of the cells
    // its hull covers: no term below it is needed anywhere in the hull.
    Mat hull_ln_delta;
    struct LogCell {  // a cell with some ln δ_p below min_log_delta
        std::size_t k0, k, lo, hi;
        Col ln_delta;
    };
    std::vector<LogCell> log_cells;
};

// Pass 1, per cell: the thresholds δ_j and, per candidate segment (not
// summed by the recursions), the frames within its cut-off distances
// r = (max_p (ln α_p − ln δ_p)/θ_p)^(1/c) before the centre (φ after); each
// segment keeps the hull of its frames over all cells (a superset: extra
// terms only bring the sum nearer the full one).
// Fills `out`, reusing its storage.
template <int P>
void cm_cut_offs(const CmTable<P>& s, std::span<const double> times, const std::vector<char>& recursive,
                 CmCutOffs<P>& out) {
    using Col = typename CmTable<P>::Col;
    using Index = Eigen::Index;
    constexpr std::size_t none = CmCutOffs<P>::none;
    const std::size_t n = s.n, frames = times.size();
    out.hull_lo.assign(n, none);
    out.hull_hi.assign(n, 0);
    out.hull_ln_delta.resize(P, static_cast<Index>(n));
    out.hull_ln_delta.setConstant(std::numeric_limits<double>::infinity());
    out.log_cells.clear();
    const bool all_recursive = std::all_of(recursive.begin(), recursive.end(), [](char r) { return r != 0; });
    // (All summed by the recursions: nothing left for the bound.)
    for_each_cell(s.tau, times, all_recursive ? frames : 0, [&](std::size_t j, std::size_t k0, std::size_t k) {
        const double ta = times[k0], tb = times[k - 1];
        // L_j, the owner's smallest dominance over the cell's frames (D_j is
        // unimodal, so at an end), and the thresholds δ_j.
        const Col ln_delta = s.log_dominance(j, ta).min(s.log_dominance(j, tb)) + s.ln_factor;
        // The segments that may reach δ_j somewhere in [ta, tb]: x^(1/c) is
        // monotone in c for fixed x, so the extremes of c bound every reach.
        const double x = ((s.max_log_alpha - ln_delta) / s.min_rate).maxCoeff();
        const double r = x > 0.0 ? std::max(std::pow(x, 1.0 / s.c_min), std::pow(x, 1.0 / s.c_max)) : 0.0;
        const auto lo = static_cast<std::size_t>(std::lower_bound(s.tau.begin(), s.tau.end(), ta - r) - s.tau.begin());
        const auto hi = static_cast<std::size_t>(std::upper_bound(s.tau.begin(), s.tau.end(), tb + r) - s.tau.begin());
        if ((ln_delta <= min_log_delta && s.spread > 0.0).any()) out.log_cells.push_back({k0, k, lo, hi, ln_delta});
        for (std::size_t i = lo; i < hi; ++i) {
            if (recursive[i]) continue;  // summed whole
            const double ti = s.tau[i], ci = s.c[i];
            const auto col = static_cast<Index>(i);
            // A segment already kept in an earlier cell: this whole cell lies
            // between that cell and its centre, so is taken into the hull.
            if (ti > tb && out.hull_lo[i] != none) {
                out.hull_hi[i] = std::max(out.hull_hi[i], k);
                out.hull_ln_delta.col(col) = out.hull_ln_delta.col(col).min(ln_delta);
                continue;
            }
            const Col excess = s.log_alpha.col(col) - ln_delta;  // ln α_p − ln δ_p
            const double y_before = (excess * s.inv_theta.col(col)).maxCoeff();
            if (y_before < 0.0) continue;  // below every δ_p everywhere (the sign is the same after τ)
            const double r_before = ti > ta ? reach_of(y_before, ci) : 0.0;
            const double r_after = ti <= tb ? reach_of((excess * s.inv_phi.col(col)).maxCoeff(), ci) : 0.0;
            // The kept frames [fa, fb): ti − r_before <= t <= ti + r_after.
            std::size_t fa = k0;
            while (fa < k && ti - times[fa] > r_before) ++fa;
            std::size_t fb = fa;
            while (fb < k && times[fb] - ti <= r_after) ++fb;
            if (fa == fb) continue;
            out.hull_lo[i] = std::min(out.hull_lo[i], fa);
            out.hull_hi[i] = std::max(out.hull_hi[i], fb);
            out.hull_ln_delta.col(col) = out.hull_ln_delta.col(col).min(ln_delta);
        }
        return true;
    });
}

// The same, returned.
template <int P>
CmCutOffs<P> cm_cut_offs(const CmTable<P>& s, std::span<const double> times, const std::vector<char>& recursive) {
    CmCutOffs<P> out;
    cm_cut_offs(s, times, recursive, out);
    return out;
}

// Per kept segment and side (2i before, 2i + 1 after the centre), its
// distinct rates and the reach of each: the distance r with
// ln α_p − rate·r^c = min ln δ_p over the hull's cells, largest over the
// rate's parameters (a fast rate's dominances are evaluated only near the
// centre, not over the whole hull).
template <int P>
void cm_rate_groups(const CmTable<P>& s, const CmCutOffs<P>& cut, std::vector<RateGroups<P>>& rate_groups) {
    using Index = Eigen::Index;
    rate_groups.assign(2 * s.n, RateGroups<P>{});
    for (std::size_t i = 0; i < s.n; ++i) {
        if (cut.hull_lo[i] == CmCutOffs<P>::none) continue;
        const auto col = static_cast<Index>(i);
        for (int side = 0; side < 2; ++side) {
            RateGroups<P>& g = rate_groups[2 * i + static_cast<std::size_t>(side)];
            std::array<double, P> excess;
            excess.fill(-std::numeric_limits<double>::infinity());
            for (int p = 0; p < P; ++p) {
                const double rate = side == 0 ? s.theta(p, col) : s.phi(p, col);
                int q = 0;
                while (q < g.count && g.rate[static_cast<std::size_t>(q)] != rate) ++q;
                if (q == g.count) g.rate[static_cast<std::size_t>(g.count++)] = rate;
                g.of_param[static_cast<std::size_t>(p)] = q;
                const auto uq = static_cast<std::size_t>(q);
                excess[uq] = std::max(excess[uq], s.log_alpha(p, col) - cut.hull_ln_delta(p, col));
            }
            for (int q = 0; q < g.count; ++q) {
                const auto uq = static_cast<std::size_t>(q);
                g.reach[uq] = excess[uq] >= 0.0 ? reach_of(excess[uq] / g.rate[uq], s.c[i]) : -1.0;
            }
        }
    }
}

// Frames (rows) × parameters of one block's sums, column by column, over
// storage laid out by CmBlockScratch.
template <int P>
using CmBlockSums = Eigen::Map<Eigen::Array<double, Eigen::Dynamic, P>, Eigen::Unaligned, Eigen::OuterStride<>>;

// Adds segment i's dominances on one side of its centre over frames
// [s0, s1) into the block sums (row 0 = frame b0): per distinct rate only
// over the frames within its reach, D_p = α_p·exp(−rate·|τ − t|^c) shared by
// the parameters with that rate; |τ − t|^c once per frame (libmvec,
// cm_kernel.h), or for c = 1 on uniform frames by the exact recurrence
// E(t ± h) = E(t)·exp(−rate·h) outwards from the centre. u, e: scratch.
template <int P>
void cm_add_segment_side(const CmTable<P>& s, std::span<const double> times, std::optional<double> step,
                         const RateGroups<P>& groups, std::size_t i, bool before, std::size_t s0, std::size_t s1,
                         std::size_t b0, Eigen::ArrayXd& u, Eigen::ArrayXd& e, CmBlockSums<P>& num,
                         CmBlockSums<P>& den) {
    using Index = Eigen::Index;
    const auto col = static_cast<Index>(i);
    const double ti = s.tau[i], ci = s.c[i];
    // Each rate's frames [g0, g1) within its reach; u over their union.
    std::array<std::size_t, P> g0{}, g1{};
    std::size_t u0 = s1, u1 = s0;
    for (int q = 0; q < groups.count; ++q) {
        const auto uq = static_cast<std::size_t>(q);
        const double r = groups.reach[uq];
        std::size_t a = s0, z = s1;
        if (r < 0.0) {
            a = z;
        } else if (before) {
            while (a < z && ti - times[a] > r) ++a;
        } else {
            while (z > a && times[z - 1] - ti > r) --z;
        }
        g0[uq] = a;
        g1[uq] = z;
        if (a < z) {
            u0 = std::min(u0, a);
            u1 = std::max(u1, z);
        }
    }
    if (u0 >= u1) return;
    const auto ulen = static_cast<Index>(u1 - u0);
    const bool recurrence = step && ci == 1.0;
    if (!recurrence) {
        const Eigen::Map<const Eigen::ArrayXd> t_side(times.data() + u0, ulen);
        if (before)
            u = ti - t_side;
        else
            u = t_side - ti;
        if (ci == 2.0)
            u = u.square();
        else if (ci != 1.0)
            cm_power(u.data(), u1 - u0, ci);  // exp(c·ln|τ − t|), ln 0 = −∞ gives 0
    }
    e.resize(ulen);
    for (int q = 0; q < groups.count; ++q) {
        const auto uq = static_cast<std::size_t>(q);
        const std::size_t a = g0[uq], z = g1[uq];
        if (a >= z) continue;
        const auto len = static_cast<Index>(z - a);
        const double rate = groups.rate[uq];
        const auto row = static_cast<Index>(a - b0);
        if (!recurrence) {
            // D_p = α_p·exp(−rate·|τ − t|^c) into the sums of the rate's parameters.
            std::array<double, P> scale_num, scale_den;
            std::array<double*, P> num_at, den_at;
            int count = 0;
            for (int p = 0; p < P; ++p) {
                if (groups.of_param[static_cast<std::size_t>(p)] != q) continue;
                const auto uc = static_cast<std::size_t>(count++);
                scale_num[uc] = s.target_alpha(p, col);
                scale_den[uc] = s.alpha(p, col);
                num_at[uc] = num.col(p).data() + row;
                den_at[uc] = den.col(p).data() + row;
            }
            cm_accumulate(u.data() + (a - u0), z - a, rate, count, scale_num.data(), scale_den.data(), num_at.data(),
                          den_at.data());
            continue;
        }
        auto eg = e.head(len);
        {
            // Outwards from the frame nearest the centre, each step
            // multiplying by exp(−rate·h) <= 1 (no overflow; values
            // that fall below the range of doubles are negligible).
            const double fall = std::exp(-rate * *step);
            if (before) {
                eg[len - 1] = std::exp(-rate * (ti - times[z - 1]));
                for (Index f = len - 1; f > 0; --f) eg[f - 1] = eg[f] * fall;
            } else {
                eg[0] = std::exp(-rate * (times[a] - ti));
                for (Index f = 1; f < len; ++f) eg[f] = eg[f - 1] * fall;
            }
        }
        for (int p = 0; p < P; ++p) {
            if (groups.of_param[static_cast<std::size_t>(p)] != q) continue;
            num.col(p).segment(row, len) += s.target_alpha(p, col) * eg;
            den.col(p).segment(row, len) += s.alpha(p, col) * eg;
        }
    }
}

// Per frame the P parameters' sums (numerator or denominator of eq. 8).
template <int P>
using CmFrameSums = std::vector<std::array<double, static_cast<std::size_t>(P)>>;

// Pass 2's working storage, kept between calls by the caller (no fresh
// pages for every utterance).
template <int P>
struct CmBlockScratch {
    std::vector<RateGroups<P>> rate_groups;
    std::vector<std::size_t> block_start, block_segments, fill;
    Eigen::ArrayXd u, e;
    std::vector<double> storage;  // the block sums, see sums()

    // The numerator and denominator sums of a block of `rows` frames. Each
    // column starts on a 64-byte boundary (the kernels' 4-wide loads and
    // stores never straddle cache lines), and columns and the two arrays are
    // spaced off multiples of 4 KiB (no false store-to-load aliasing between
    // the columns the kernel updates together).
    std::pair<CmBlockSums<P>, CmBlockSums<P>> sums(std::size_t rows) {
        const std::size_t stride = (rows + 7) / 8 * 8 + 8;  // doubles; 64-byte multiple, not 4 KiB
        const std::size_t each = stride * static_cast<std::size_t>(P) + 8;
        storage.resize(2 * each + 8);
        double* base = storage.data();
        while (reinterpret_cast<std::uintptr_t>(base) % 64 != 0) ++base;
        const auto r = static_cast<Eigen::Index>(rows), st = static_cast<Eigen::Index>(stride);
        return {CmBlockSums<P>(base, r, P, Eigen::OuterStride<>(st)),
                CmBlockSums<P>(base + each, r, P, Eigen::OuterStride<>(st))};
    }
};

// Pass 2: each kept segment's dominances over its hull, summed per frame as
// absolute values (every kept one is >= δ_j > e^−680, none overflows), onto
// the recursions' sums (rec_num, rec_den; null when there are none), in
// blocks of 256 frames so the sums stay small and in cache; then
// sink(f, p, z) for every frame and parameter.
template <int P, class Sink>
void cm_accumulate_blocks(const CmTable<P>& s, std::span<const double> times, std::optional<double> step,
                          const CmCutOffs<P>& cut, const CmFrameSums<P>* rec_num, const CmFrameSums<P>* rec_den,
                          CmBlockScratch<P>& scratch, const Sink& sink) {
    using Index = Eigen::Index;
    constexpr std::size_t none = CmCutOffs<P>::none;
    const std::size_t n = s.n, frames = times.size();
    constexpr std::size_t block = 256;
    const std::size_t blocks = (frames + block - 1) / block;
    // The segments overlapping each block (compressed rows).
    auto& block_start = scratch.block_start;
    auto& block_segments = scratch.block_segments;
    block_start.assign(blocks + 1, 0);
    for (std::size_t i = 0; i < n; ++i)
        if (cut.hull_lo[i] != none)
            for (std::size_t b = cut.hull_lo[i] / block; b <= (cut.hull_hi[i] - 1) / block; ++b) ++block_start[b + 1];
    for (std::size_t b = 0; b < blocks; ++b) block_start[b + 1] += block_start[b];
    block_segments.resize(block_start[blocks]);
    {
        auto& fill = scratch.fill;
        fill.assign(block_start.begin(), block_start.end() - 1);
        for (std::size_t i = 0; i < n; ++i)
            if (cut.hull_lo[i] != none)
                for (std::size_t b = cut.hull_lo[i] / block; b <= (cut.hull_hi[i] - 1) / block; ++b)
                    block_segments[fill[b]++] = i;
    }
    cm_rate_groups(s, cut, scratch.rate_groups);
    const std::vector<RateGroups<P>>& rate_groups = scratch.rate_groups;
    auto [num, den] = scratch.sums(block);
    Eigen::ArrayXd& u = scratch.u;
    Eigen::ArrayXd& e = scratch.e;
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t b0 = b * block, b1 = std::min(frames, b0 + block);
        num.setZero();
        den.setZero();
        if (rec_num)  // (column by column: the block sums are column-major)
            for (int p = 0; p < P; ++p)
                for (std::size_t f = b0; f < b1; ++f) {
                    num(static_cast<Index>(f - b0), p) = (*rec_num)[f][static_cast<std::size_t>(p)];
                    den(static_cast<Index>(f - b0), p) = (*rec_den)[f][static_cast<std::size_t>(p)];
                }
        for (std::size_t q_seg = block_start[b]; q_seg < block_start[b + 1]; ++q_seg) {
            const std::size_t i = block_segments[q_seg];
            const std::size_t h0 = std::max(cut.hull_lo[i], b0), h1 = std::min(cut.hull_hi[i], b1);
            const auto split = static_cast<std::size_t>(
                std::lower_bound(times.begin() + static_cast<std::ptrdiff_t>(h0),
                                 times.begin() + static_cast<std::ptrdiff_t>(h1), s.tau[i]) -
                times.begin());
            // Before the centre [h0, split) with θ, after it [split, h1) with φ.
            if (h0 < split)
                cm_add_segment_side(s, times, step, rate_groups[2 * i], i, true, h0, split, b0, u, e, num, den);
            if (split < h1)
                cm_add_segment_side(s, times, step, rate_groups[2 * i + 1], i, false, split, h1, b0, u, e, num, den);
        }
        for (std::size_t f = b0; f < b1; ++f) {
            const auto row = static_cast<Index>(f - b0);
            for (int p = 0; p < P; ++p)
                sink(f, static_cast<std::size_t>(p), s.spread[p] == 0.0 ? s.t_min[p] : num(row, p) / den(row, p));
        }
    }
}

// The cells whose thresholds are below e^−680 for some parameter (extreme
// dominance ranges, where absolute dominances could underflow): those
// parameters' values at the cell's frames by the model's pointwise sum
// (CmPointwiseSum: log domain, shifted by the largest dominance, within
// N·e^−40 of the target spread of the full sum), given to sink(f, p, z).
template <int P, class Sink>
void cm_log_domain_cells(const CmTable<P>& s, std::span<const double> times,
                         const std::vector<typename CmCutOffs<P>::LogCell>& cells, const Sink& sink) {
    if (cells.empty()) return;
    std::array<std::vector<CmSegment>, P> segments;  // per parameter, ascending τ
    std::array<std::optional<CmPointwiseSum>, P> sums;
    for (const auto& cell : cells)
        for (int p = 0; p < P; ++p) {
            const auto up = static_cast<std::size_t>(p);
            if (!(cell.ln_delta[p] <= min_log_delta && s.spread[p] > 0.0)) continue;
            if (!sums[up]) {
                for (std::size_t i = 0; i < s.n; ++i) {
                    const auto col = static_cast<Eigen::Index>(i);
                    segments[up].push_back(
                        {s.tau[i], s.target(p, col), s.alpha(p, col), s.theta(p, col), s.phi(p, col), s.c[i]});
                }
                sums[up].emplace(segments[up]);
            }
            for (std::size_t f = cell.k0; f < cell.k; ++f) sink(f, up, sums[up]->evaluate(times[f]));
        }
}

}  // namespace
}  // namespace avsi::synth::detail
