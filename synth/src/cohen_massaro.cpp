// The Cohen-Massaro model (Beskow §4.2, eq. 7–8): dominance functions, the
// full and the bounded (linear-time) weighted sums, and the model file.
// The bound is derived in cohen_massaro.h.
#include "avsi/synth/cohen_massaro.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>

#include <Eigen/Core>

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "cm_kernel.h"
#include "model_json.h"

namespace avsi::synth {

namespace {

// Segment i's term at t with ln D_i(t) (eq. 7) in `weight`: x = |τ_i − t|,
// x^c as exp(c·ln x) (exactly x for c = 1, when ln x is computed only if
// asked for).
inline CmTerm segment_term(const CmSegment& s, double log_alpha, std::uint32_t i, double t, bool need_log_x) {
    CmTerm term{i, t < s.tau_s, std::abs(s.tau_s - t), 0.0, 0.0, 0.0};
    if (term.distance_s > 0 && (need_log_x || s.c != 1.0)) term.log_distance = std::log(term.distance_s);
    term.distance_c = s.c == 1.0 ? term.distance_s : (term.distance_s > 0 ? std::exp(s.c * term.log_distance) : 0.0);
    term.weight = log_alpha - (term.before ? s.theta_per_s : s.phi_per_s) * term.distance_c;
    return term;
}

void check_segment(const CmSegment& s) {
    AVSI_ASSERT(s.alpha > 0.0 && s.theta_per_s > 0.0 && s.phi_per_s > 0.0 && s.c > 0.0);
}

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

// The bounded sum of eq. 8 (derivation in cohen_massaro.h) for P parameters
// whose segments share centre and exponent: source(p, i) is parameter p's
// segment i (any order); sink(frame, p, z) receives each value.
// Pass 1, per cell: the thresholds δ_j and, per candidate segment, the frames
// within its cut-off distances r = (max_p (ln α_p − ln δ_p)/θ_p)^(1/c) before
// the centre (φ after); each segment keeps the hull of its frames over all
// cells (a superset: extra terms only bring the sum nearer the full one).
// Pass 2, per segment over its hull: |τ − t|^c once per frame, then
// exp(−rate·|τ − t|^c) once per distinct rate of the segment, shared by the
// parameters with that rate (D_p = α_p·exp(−rate_p·|τ − t|^c)), vectorised
// over the frames (Eigen); for c = 1 on uniformly spaced frames by the exact
// recurrence E(t ± h) = E(t)·exp(−rate·h) outwards from the centre.
template <int P, class Source, class Sink>
void bounded_sum(std::size_t n, const Source& source, std::span<const double> times, double tolerance,
                 const Sink& sink) {
    using Col = Eigen::Array<double, P, 1>;
    using Mat = Eigen::Array<double, P, Eigen::Dynamic>;
    using Index = Eigen::Index;
    // Step 1: segments sorted by centre; per parameter the target spread and
    // the extremes for the reach bound.
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return source(0, a).tau_s < source(0, b).tau_s; });
    std::vector<double> tau(n), cexp(n);
    Mat target(P, n), log_alpha(P, n), theta(P, n), phi(P, n);
    for (std::size_t i = 0; i < n; ++i) {
        tau[i] = source(0, order[i]).tau_s;
        cexp[i] = source(0, order[i]).c;
        for (int p = 0; p < P; ++p) {
            const CmSegment& s = source(static_cast<std::size_t>(p), order[i]);
            AVSI_ASSERT(s.alpha > 0.0 && s.theta_per_s > 0.0 && s.phi_per_s > 0.0 && s.c > 0.0);
            const auto col = static_cast<Index>(i);
            target(p, col) = s.target;
            log_alpha(p, col) = std::log(s.alpha);
            theta(p, col) = s.theta_per_s;
            phi(p, col) = s.phi_per_s;
        }
    }
    const Mat alpha = log_alpha.exp(), target_alpha = target * alpha;
    const Mat inv_theta = theta.inverse(), inv_phi = phi.inverse();
    const Col t_min = target.rowwise().minCoeff(), spread = target.rowwise().maxCoeff() - t_min;
    const Col max_log_alpha = log_alpha.rowwise().maxCoeff();
    const Col min_rate = theta.rowwise().minCoeff().min(phi.rowwise().minCoeff());
    const double c_min = *std::min_element(cexp.begin(), cexp.end());
    const double c_max = *std::max_element(cexp.begin(), cexp.end());
    // δ_j = ε·L_j/(ΔT·N): ln δ_j = ln L_j + ln_factor (never above ln L_j).
    Col ln_factor;
    for (int p = 0; p < P; ++p)
        ln_factor[p] = spread[p] > 0.0
                           ? std::min(0.0, std::log(tolerance) - std::log(spread[p]) - std::log(static_cast<double>(n)))
                           : 0.0;
    auto log_dom_col = [&](std::size_t i, double t) -> Col {
        const double d = tau[i] - t;
        const double u = power(std::abs(d), cexp[i]);
        const auto col = static_cast<Index>(i);
        if (d > 0.0) return log_alpha.col(col) - theta.col(col) * u;
        return log_alpha.col(col) - phi.col(col) * u;
    };
    // The distance r >= 0 at which rate·r^c = y (y >= 0).
    auto reach_of = [](double y, double c) {
        return c == 1.0 ? y : c == 2.0 ? std::sqrt(y) : y > 0.0 ? std::exp(std::log(y) / c) : 0.0;
    };

    const std::size_t frames = times.size();
    // Uniformly spaced times allow the c = 1 recursions (recursive_sums) and
    // the c = 1 recurrence below.
    bool uniform = frames >= 2;
    const double step = uniform ? (times[frames - 1] - times[0]) / static_cast<double>(frames - 1) : 0.0;
    for (std::size_t f = 0; uniform && f < frames; ++f)
        uniform = std::abs(times[f] - (times[0] + step * static_cast<double>(f))) <= 1e-12 * (1.0 + std::abs(times[f]));
    // The segments with c = 1 are summed whole by recursive_sums (exact, no
    // bound needed) where the frames are uniform and no sum can underflow:
    // every cell owner's dominance above e^−600 at its cell's frames (so the
    // flushed subnormals are negligible) and no cell needing the log domain.
    std::vector<char> recursive(n, 0);
    bool any_recursive = false;
    if (uniform) {
        for (std::size_t i = 0; i < n; ++i) any_recursive |= (recursive[i] = cexp[i] == 1.0) != 0;
        for (std::size_t j = 0, kk = 0; any_recursive && j < n && kk < frames; ++j) {
            const double upper = j + 1 < n ? 0.5 * (tau[j] + tau[j + 1]) : std::numeric_limits<double>::infinity();
            const std::size_t k0 = kk;
            while (kk < frames && times[kk] < upper) ++kk;
            if (kk == k0) continue;
            const Col ln_l = log_dom_col(j, times[k0]).min(log_dom_col(j, times[kk - 1]));
            if ((spread > 0.0 && (ln_l <= -600.0 || ln_l + ln_factor <= min_log_delta)).any()) any_recursive = false;
        }
        if (!any_recursive) std::fill(recursive.begin(), recursive.end(), 0);
    }

    // Pass 1: per cell the thresholds, per segment the hull of its kept frames.
    constexpr std::size_t none = std::numeric_limits<std::size_t>::max();
    std::vector<std::size_t> hull_lo(n, none), hull_hi(n, 0);
    // Per kept segment and parameter the lowest threshold ln δ_p of the cells
    // its hull covers: no term below it is needed anywhere in the hull.
    Mat hull_ln_delta = Mat::Constant(P, static_cast<Index>(n), std::numeric_limits<double>::infinity());
    struct LogCell {  // a cell with some ln δ_p below min_log_delta
        std::size_t k0, k, lo, hi;
        Col ln_delta;
    };
    std::vector<LogCell> log_cells;
    const bool all_recursive = std::all_of(recursive.begin(), recursive.end(), [](char r) { return r != 0; });
    std::size_t k = all_recursive ? frames : 0;  // nothing left for the bound
    for (std::size_t j = 0; j < n && k < frames; ++j) {
        // Step 2: the frames of cell j (nearer τ_j than the next centre).
        const double upper = j + 1 < n ? 0.5 * (tau[j] + tau[j + 1]) : std::numeric_limits<double>::infinity();
        const std::size_t k0 = k;
        while (k < frames && times[k] < upper) ++k;
        if (k == k0) continue;
        const double ta = times[k0], tb = times[k - 1];
        // Step 3: L_j, the owner's smallest dominance over the cell's frames
        // (D_j is unimodal, so at an end), and the thresholds δ_j.
        const Col ln_delta = log_dom_col(j, ta).min(log_dom_col(j, tb)) + ln_factor;
        // Step 4: the segments that may reach δ_j somewhere in [ta, tb]: x^(1/c)
        // is monotone in c for fixed x, so the extremes of c bound every reach.
        const double x = ((max_log_alpha - ln_delta) / min_rate).maxCoeff();
        const double r = x > 0.0 ? std::max(std::pow(x, 1.0 / c_min), std::pow(x, 1.0 / c_max)) : 0.0;
        const auto lo = static_cast<std::size_t>(std::lower_bound(tau.begin(), tau.end(), ta - r) - tau.begin());
        const auto hi = static_cast<std::size_t>(std::upper_bound(tau.begin(), tau.end(), tb + r) - tau.begin());
        if ((ln_delta <= min_log_delta && spread > 0.0).any()) log_cells.push_back({k0, k, lo, hi, ln_delta});
        for (std::size_t i = lo; i < hi; ++i) {
            if (recursive[i]) continue;  // summed whole, see above
            const double ti = tau[i], ci = cexp[i];
            // A segment already kept in an earlier cell: this whole cell lies
            // between that cell and its centre, so is taken into the hull.
            if (ti > tb && hull_lo[i] != none) {
                hull_hi[i] = std::max(hull_hi[i], k);
                hull_ln_delta.col(static_cast<Index>(i)) = hull_ln_delta.col(static_cast<Index>(i)).min(ln_delta);
                continue;
            }
            const auto col = static_cast<Index>(i);
            const Col excess = log_alpha.col(col) - ln_delta;  // ln α_p − ln δ_p
            const double y_before = (excess * inv_theta.col(col)).maxCoeff();
            if (y_before < 0.0) continue;  // below every δ_p everywhere (the sign is the same after τ)
            const double r_before = ti > ta ? reach_of(y_before, ci) : 0.0;
            const double r_after = ti <= tb ? reach_of((excess * inv_phi.col(col)).maxCoeff(), ci) : 0.0;
            // The kept frames [fa, fb): ti − r_before <= t <= ti + r_after.
            std::size_t fa = k0;
            while (fa < k && ti - times[fa] > r_before) ++fa;
            std::size_t fb = fa;
            while (fb < k && times[fb] - ti <= r_after) ++fb;
            if (fa == fb) continue;
            hull_lo[i] = std::min(hull_lo[i], fa);
            hull_hi[i] = std::max(hull_hi[i], fb);
            hull_ln_delta.col(col) = hull_ln_delta.col(col).min(ln_delta);
        }
    }

    // Pass 2: each segment's dominances over its hull, summed per frame as
    // absolute values (every kept one is >= δ_j > e^−680, none overflows),
    // in blocks of frames so the sums stay small and in cache.
    constexpr std::size_t block = 256;
    const std::size_t blocks = (frames + block - 1) / block;
    // The segments overlapping each block (compressed rows).
    std::vector<std::size_t> block_start(blocks + 1, 0), block_segments;
    for (std::size_t i = 0; i < n; ++i)
        if (hull_lo[i] != none)
            for (std::size_t b = hull_lo[i] / block; b <= (hull_hi[i] - 1) / block; ++b) ++block_start[b + 1];
    for (std::size_t b = 0; b < blocks; ++b) block_start[b + 1] += block_start[b];
    block_segments.resize(block_start[blocks]);
    {
        std::vector<std::size_t> fill(block_start.begin(), block_start.end() - 1);
        for (std::size_t i = 0; i < n; ++i)
            if (hull_lo[i] != none)
                for (std::size_t b = hull_lo[i] / block; b <= (hull_hi[i] - 1) / block; ++b) block_segments[fill[b]++] = i;
    }
    const Eigen::Map<const Eigen::ArrayXd> t_all(times.data(), static_cast<Index>(frames));
    using Frames = Eigen::Array<double, Eigen::Dynamic, P>;  // frames × parameters
    Frames num(static_cast<Index>(block), P), den(static_cast<Index>(block), P);
    // The c = 1 segments' sums per frame (kept per thread between calls: no
    // fresh pages for every utterance).
    static thread_local std::vector<std::array<double, static_cast<std::size_t>(P)>> rec_num, rec_den;
    if (any_recursive) {
        rec_num.assign(frames, {});
        rec_den.assign(frames, {});
        recursive_sums<P>(times, step, tau, recursive, theta, phi, alpha, target_alpha, rec_num, rec_den);
    }
    // Per kept segment and side, its distinct rates and the reach of each:
    // the distance r with ln α_p − rate·r^c = min ln δ_p over the hull's
    // cells, largest over the rate's parameters (a fast rate's dominances
    // are evaluated only near the centre, not over the whole hull).
    std::vector<RateGroups<P>> rate_groups(2 * n);
    for (std::size_t i = 0; i < n; ++i) {
        if (hull_lo[i] == none) continue;
        const auto col = static_cast<Index>(i);
        for (int side = 0; side < 2; ++side) {
            RateGroups<P>& g = rate_groups[2 * i + static_cast<std::size_t>(side)];
            std::array<double, P> excess;
            excess.fill(-std::numeric_limits<double>::infinity());
            for (int p = 0; p < P; ++p) {
                const double rate = side == 0 ? theta(p, col) : phi(p, col);
                int q = 0;
                while (q < g.count && g.rate[static_cast<std::size_t>(q)] != rate) ++q;
                if (q == g.count) g.rate[static_cast<std::size_t>(g.count++)] = rate;
                g.of_param[static_cast<std::size_t>(p)] = q;
                const auto uq = static_cast<std::size_t>(q);
                excess[uq] = std::max(excess[uq], log_alpha(p, col) - hull_ln_delta(p, col));
            }
            for (int q = 0; q < g.count; ++q) {
                const auto uq = static_cast<std::size_t>(q);
                g.reach[uq] = excess[uq] >= 0.0 ? reach_of(excess[uq] / g.rate[uq], cexp[i]) : -1.0;
            }
        }
    }
    Eigen::ArrayXd u, e;
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t b0 = b * block, b1 = std::min(frames, b0 + block);
        num.setZero();
        den.setZero();
        if (any_recursive)
            for (std::size_t f = b0; f < b1; ++f)
                for (int p = 0; p < P; ++p) {
                    num(static_cast<Index>(f - b0), p) = rec_num[f][static_cast<std::size_t>(p)];
                    den(static_cast<Index>(f - b0), p) = rec_den[f][static_cast<std::size_t>(p)];
                }
        for (std::size_t q_seg = block_start[b]; q_seg < block_start[b + 1]; ++q_seg) {
            const std::size_t i = block_segments[q_seg];
            const auto col = static_cast<Index>(i);
            const double ti = tau[i], ci = cexp[i];
            const std::size_t h0 = std::max(hull_lo[i], b0), h1 = std::min(hull_hi[i], b1);
            const auto split = static_cast<std::size_t>(
                std::lower_bound(times.begin() + static_cast<std::ptrdiff_t>(h0),
                                 times.begin() + static_cast<std::ptrdiff_t>(h1), ti) -
                times.begin());
            for (int side = 0; side < 2; ++side) {
                // Before the centre [h0, split) with θ, after it [split, h1) with φ.
                const bool before = side == 0;
                const std::size_t s0 = before ? h0 : split, s1 = before ? split : h1;
                if (s0 >= s1) continue;
                const RateGroups<P>& groups = rate_groups[2 * i + (before ? 0 : 1)];
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
                if (u0 >= u1) continue;
                const auto ulen = static_cast<Index>(u1 - u0);
                const bool recurrence = uniform && ci == 1.0;
                if (!recurrence) {
                    const auto t_side = t_all.segment(static_cast<Index>(u0), ulen);
                    if (before)
                        u = ti - t_side;
                    else
                        u = t_side - ti;
                    if (ci == 2.0)
                        u = u.square();
                    else if (ci != 1.0)
                        detail::cm_power(u.data(), u1 - u0, ci);  // exp(c·ln|τ − t|), ln 0 = −∞ gives 0
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
                            scale_num[uc] = target_alpha(p, col);
                            scale_den[uc] = alpha(p, col);
                            num_at[uc] = num.col(p).data() + row;
                            den_at[uc] = den.col(p).data() + row;
                        }
                        detail::cm_accumulate(u.data() + (a - u0), z - a, rate, count, scale_num.data(),
                                              scale_den.data(), num_at.data(), den_at.data());
                        continue;
                    }
                    auto eg = e.head(len);
                    {
                        // Outwards from the frame nearest the centre, each step
                        // multiplying by exp(−rate·h) <= 1 (no overflow; values
                        // that fall below the range of doubles are negligible).
                        const double fall = std::exp(-rate * step);
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
                        num.col(p).segment(row, len) += target_alpha(p, col) * eg;
                        den.col(p).segment(row, len) += alpha(p, col) * eg;
                    }
                }
            }
        }
        for (std::size_t f = b0; f < b1; ++f) {
            const auto row = static_cast<Index>(f - b0);
            for (int p = 0; p < P; ++p)
                sink(f, static_cast<std::size_t>(p), spread[p] == 0.0 ? t_min[p] : num(row, p) / den(row, p));
        }
    }
    // Cells with extreme dominance ranges: per frame in the log domain,
    // shifted by the largest dominance.
    for (const LogCell& cell : log_cells)
        for (int p = 0; p < P; ++p) {
            if (!(cell.ln_delta[p] <= min_log_delta && spread[p] > 0.0)) continue;
            for (std::size_t f = cell.k0; f < cell.k; ++f) {
                double top = -std::numeric_limits<double>::infinity();
                for (std::size_t i = cell.lo; i < cell.hi; ++i) top = std::max(top, log_dom_col(i, times[f])[p]);
                double num_f = 0.0, den_f = 0.0;
                for (std::size_t i = cell.lo; i < cell.hi; ++i) {
                    const double l = log_dom_col(i, times[f])[p];
                    if (l < cell.ln_delta[p]) continue;
                    const double w = std::exp(l - top);
                    num_f += target(p, static_cast<Index>(i)) * w;
                    den_f += w;
                }
                sink(f, static_cast<std::size_t>(p), num_f / den_f);
            }
        }
}

}  // namespace

double log_dominance(const CmSegment& segment, double t_s) {
    check_segment(segment);
    return segment_term(segment, std::log(segment.alpha), 0, t_s, false).weight;
}

double dominance(const CmSegment& segment, double t_s) { return std::exp(log_dominance(segment, t_s)); }

CmPointwiseSum::CmPointwiseSum(std::span<const CmSegment> s, double skip_log_ratio)
    : m_s(s),
      m_skip_log_ratio(skip_log_ratio),
      m_log_alpha(s.size()),
      m_max_log_alpha(-std::numeric_limits<double>::infinity()),
      m_min_theta(std::numeric_limits<double>::infinity()),
      m_min_phi(std::numeric_limits<double>::infinity()),
      m_min_c(std::numeric_limits<double>::infinity()) {
    AVSI_ASSERT(!s.empty());
    for (std::size_t i = 0; i < s.size(); ++i) {
        check_segment(s[i]);
        AVSI_ASSERT(i == 0 || s[i].tau_s >= s[i - 1].tau_s);
        m_log_alpha[i] = std::log(s[i].alpha);
        m_max_log_alpha = std::max(m_max_log_alpha, m_log_alpha[i]);
        m_min_theta = std::min(m_min_theta, s[i].theta_per_s);
        m_min_phi = std::min(m_min_phi, s[i].phi_per_s);
        m_min_c = std::min(m_min_c, s[i].c);
        m_max_c = std::max(m_max_c, s[i].c);
    }
}

double CmPointwiseSum::collect(double t, bool need_log_x) {
    m_terms.clear();
    const std::size_t n = m_s.size();
    const auto first_after = static_cast<std::size_t>(
        std::lower_bound(m_s.begin(), m_s.end(), t, [](const CmSegment& s, double v) { return s.tau_s < v; }) -
        m_s.begin());
    double m = -std::numeric_limits<double>::infinity();
    auto add = [&](std::size_t i) {
        m_terms.push_back(segment_term(m_s[i], m_log_alpha[i], static_cast<std::uint32_t>(i), t, need_log_x));
        m = std::max(m, m_terms.back().weight);
    };
    if (first_after > 0) add(first_after - 1);
    if (first_after < n) add(first_after);
    // Anticipatory side (later centres, θ), then carry-over side (earlier, φ).
    double reach_m = m, reach = max_distance(m, m_min_theta);
    for (std::size_t i = first_after + 1; i < n; ++i) {
        if (m != reach_m) reach = max_distance(reach_m = m, m_min_theta);
        if (m_s[i].tau_s - t > reach) break;
        add(i);
    }
    reach_m = m;
    reach = max_distance(m, m_min_phi);
    for (std::size_t i = first_after >= 1 ? first_after - 1 : 0; i-- > 0;) {
        if (m != reach_m) reach = max_distance(reach_m = m, m_min_phi);
        if (t - m_s[i].tau_s > reach) break;
        add(i);
    }
    return m;
}

double CmPointwiseSum::max_distance(double m, double rate) const {
    const double y = (m_max_log_alpha - m + m_skip_log_ratio) / rate;
    if (y <= 0) return 0.0;
    const double c = y < 1.0 ? m_max_c : m_min_c;
    return c == 1.0 ? y : std::pow(y, 1.0 / c);
}

double CmPointwiseSum::evaluate(double t_s, bool need_log_distance) {
    const double m = collect(t_s, need_log_distance);
    // ln D_i − max ln D, then D_i / max D (vectorised), and eq. 8.
    m_ratio.resize(m_terms.size());
    for (std::size_t e = 0; e < m_terms.size(); ++e) m_ratio[e] = m_terms[e].weight - m;
    detail::cm_exp(m_ratio.data(), m_ratio.size());
    double sum = 0.0, num = 0.0;
    for (std::size_t e = 0; e < m_terms.size(); ++e) {
        CmTerm& term = m_terms[e];
        term.weight = m_ratio[e];
        sum += term.weight;
        num += term.weight * m_s[term.segment].target;
    }
    m_weight_sum = sum;
    return num / sum;
}

void cohen_massaro_full(std::span<const CmSegment> segments, std::span<const double> times_s,
                        std::span<double> out) {
    AVSI_ASSERT(!segments.empty() && out.size() == times_s.size());
    const auto by_centre = [](const CmSegment& a, const CmSegment& b) { return a.tau_s < b.tau_s; };
    std::vector<CmSegment> sorted;
    if (!std::is_sorted(segments.begin(), segments.end(), by_centre)) {
        sorted.assign(segments.begin(), segments.end());
        std::stable_sort(sorted.begin(), sorted.end(), by_centre);
        segments = sorted;
    }
    CmPointwiseSum sum(segments, std::numeric_limits<double>::infinity());
    for (std::size_t k = 0; k < times_s.size(); ++k) out[k] = sum.evaluate(times_s[k]);
}

void cohen_massaro_bounded(std::span<const CmSegment> segments, std::span<const double> times_s,
                           std::span<double> out, double tolerance) {
    AVSI_ASSERT(!segments.empty() && out.size() == times_s.size());
    AVSI_ASSERT(std::is_sorted(times_s.begin(), times_s.end()));
    if (!(tolerance > 0.0)) {
        cohen_massaro_full(segments, times_s, out);
        return;
    }
    bounded_sum<1>(
        segments.size(), [&](std::size_t, std::size_t i) -> const CmSegment& { return segments[i]; }, times_s,
        tolerance, [&](std::size_t f, std::size_t, double value) { out[f] = value; });
}

void cohen_massaro_bounded_all(const std::array<std::vector<CmSegment>, param_count>& segments,
                               std::span<const double> times_s, std::vector<Frame>& out, double tolerance) {
    AVSI_ASSERT(std::is_sorted(times_s.begin(), times_s.end()));
    out.assign(times_s.size(), Frame{});
    const std::size_t n = segments[0].size();
    bool shared = n > 0 && tolerance > 0.0;
    for (std::size_t p = 1; shared && p < param_count; ++p) {
        shared = segments[p].size() == n;
        for (std::size_t i = 0; shared && i < n; ++i)
            shared = segments[p][i].tau_s == segments[0][i].tau_s && segments[p][i].c == segments[0][i].c;
    }
    if (shared) {
        bounded_sum<static_cast<int>(param_count)>(
            n, [&](std::size_t p, std::size_t i) -> const CmSegment& { return segments[p][i]; }, times_s, tolerance,
            [&](std::size_t f, std::size_t p, double value) { out[f][p] = value; });
        return;
    }
    std::vector<double> values(times_s.size());
    for (std::size_t p = 0; p < param_count; ++p) {
        cohen_massaro_bounded(segments[p], times_s, values, tolerance);
        for (std::size_t k = 0; k < values.size(); ++k) out[k][p] = values[k];
    }
}

std::vector<CmSegment> DominanceModel::segments(const PhoneSequence& phones, Param param) const {
    return std::move(segments_all(phones)[index(param)]);
}

void DominanceModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                              std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    cohen_massaro_bounded_all(segments_all(phones), times_s, out, tolerance);
}

std::array<std::vector<CmSegment>, param_count> CohenMassaroModel::segments_all(const PhoneSequence& phones) const {
    std::array<std::vector<CmSegment>, param_count> out;
    for (auto& v : out) v.reserve(phones.size());
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const CohenMassaroPhone* entry = find_phone_entry(m_phones, phones[i]);
        if (!entry) detail::missing_phone(phones[i], i, kind());
        const double tau = phones[i].centre_s();
        for (std::size_t p = 0; p < param_count; ++p) {
            const CohenMassaroParams& q = entry->params[p];
            out[p].push_back({tau, q.target, q.alpha, q.theta_per_s, q.phi_per_s, entry->c});
        }
    }
    return out;
}

std::string CohenMassaroModel::to_json_text() const {
    using detail::json;
    json j = detail::model_header(*this);
    json phones = json::object();
    for (const auto& [key, entry] : m_phones) {
        json ps = json::object();
        for (const auto& info : params()) {
            const CohenMassaroParams& q = entry.params[index(info.param)];
            ps[std::string(info.name)] =
                json{{"target", q.target}, {"alpha", q.alpha}, {"theta", q.theta_per_s}, {"phi", q.phi_per_s}};
        }
        phones[key] = json{{"c", entry.c}, {"params", ps}};
    }
    j["phones"] = phones;
    return j.dump(2) + "\n";
}

namespace detail {

std::unique_ptr<ControlModel> load_cohen_massaro(const json& root, const std::filesystem::path&, JsonReader& reader) {
    reader.check_keys(root, {"kind", "version", "provenance", "phones", "tolerance"}, "");
    CohenMassaroModel::Table table;
    if (const json* phones = reader.require(root, "phones", "/phones")) {
        if (!phones->is_object() || phones->empty())
            reader.error("/phones", "expected an object with one entry per phone");
        else
            for (const auto& [key, node] : phones->items()) {
                const std::string base = "/phones/" + pointer_token(key);
                if (!reader.phone_key(key, base)) continue;
                if (!node.is_object()) {
                    reader.error(base, fmt::format("expected an object, got {}", node.dump()));
                    continue;
                }
                reader.check_keys(node, {"c", "params"}, base);
                CohenMassaroPhone entry;
                if (auto c = reader.number_field(node, "c", base + "/c", 0.0, 10.0, true)) entry.c = *c;
                const json* ps = reader.require(node, "params", base + "/params");
                if (!ps) continue;
                std::vector<std::string> names;
                for (const auto& info : params()) names.emplace_back(info.name);
                reader.check_keys(*ps, names, base + "/params", "parameter");
                for (const auto& info : params()) {
                    const std::string pp = base + "/params/" + std::string(info.name);
                    const json* q = reader.require(*ps, std::string(info.name), pp);
                    if (!q) continue;
                    reader.check_keys(*q, {"target", "alpha", "theta", "phi"}, pp);
                    CohenMassaroParams& out = entry.params[index(info.param)];
                    if (const json* t = reader.require(*q, "target", pp + "/target"))
                        if (auto v = reader.param_value(*t, info.param, pp + "/target")) out.target = *v;
                    if (auto v = reader.number_field(*q, "alpha", pp + "/alpha", 0.0, 1e6, true)) out.alpha = *v;
                    if (auto v = reader.number_field(*q, "theta", pp + "/theta", 0.0, 1e6, true)) out.theta_per_s = *v;
                    if (auto v = reader.number_field(*q, "phi", pp + "/phi", 0.0, 1e6, true)) out.phi_per_s = *v;
                }
                table[key] = entry;
            }
    }
    auto model = std::make_unique<CohenMassaroModel>(std::move(table));
    if (root.contains("tolerance"))
        if (auto v = reader.number(root["tolerance"], "/tolerance", 0.0, 1e-3)) model->tolerance = *v;
    return model;
}

}  // namespace detail
}  // namespace avsi::synth
