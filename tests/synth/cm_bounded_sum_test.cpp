// The named steps of the bounded Cohen-Massaro sum (synth/src/cm_bounded_sum.h,
// Beskow eq. 8), each on its own: the cut-offs keep every segment that
// reaches its cell's threshold, the c = 1 recursions equal the direct sums
// and are used only where they may be, the log-domain cells give the full
// sum where absolute dominances would underflow, and the block accumulation
// matches the full sum across block edges. Seeded sweeps, the seed in
// SCOPED_TRACE.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "avsi/core/rng.h"
#include "avsi/synth/cohen_massaro.h"
#include "cm_bounded_sum.h"

namespace avsi::synth {
namespace {

using detail::CmCutOffs;
using detail::CmTable;

// n random segments one after another (durations 20–300 ms); c from `c_of`.
template <class C>
std::vector<CmSegment> random_segments(Rng& rng, std::size_t n, double rate_lo, double rate_hi, const C& c_of,
                                       double& end_s) {
    std::vector<CmSegment> segs;
    double t = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double d = rng.uniform(0.02, 0.3);
        segs.push_back({t + d / 2, rng.uniform(-1.0, 1.0), rng.uniform(0.02, 3.0), rng.uniform(rate_lo, rate_hi),
                        rng.uniform(rate_lo, rate_hi), c_of()});
        t += d;
    }
    end_s = t;
    return segs;
}

std::vector<double> frame_times(double end_s, double fps) {
    std::vector<double> times(frame_count(end_s, fps));
    for (std::size_t k = 0; k < times.size(); ++k) times[k] = static_cast<double>(k) / fps;
    return times;
}

CmTable<1> table_of(const std::vector<CmSegment>& segs, double tolerance = cm_default_tolerance) {
    return detail::cm_table<1>(
        segs.size(), [&](std::size_t, std::size_t i) -> const CmSegment& { return segs[i]; }, tolerance);
}

std::vector<double> full_sum(const std::vector<CmSegment>& segs, std::span<const double> times) {
    std::vector<double> out(times.size());
    cohen_massaro_full(segs, times, out);
    return out;
}

TEST(CmBoundedSumSteps, UniformStepOnlyForEvenlySpacedFrames) {
    const std::vector<double> even = frame_times(1.0, 60.0);
    ASSERT_TRUE(detail::uniform_step(even).has_value());
    EXPECT_NEAR(*detail::uniform_step(even), 1.0 / 60.0, 1e-15);
    std::vector<double> jittered = even;
    jittered[10] += 1e-4;
    EXPECT_FALSE(detail::uniform_step(jittered).has_value());
    const double one[] = {0.5};
    EXPECT_FALSE(detail::uniform_step(one).has_value());
}

TEST(CmBoundedSumSteps, CutOffsKeepEverySegmentThatReachesItsCellsThreshold) {
    for (std::uint64_t seed = 1; seed <= 12; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        double end_s = 0.0;
        const auto segs = random_segments(rng, 60, 30.0, 120.0, [&] { return rng.uniform(0.5, 2.5); }, end_s);
        const std::vector<double> times = frame_times(end_s, 60.0);
        const CmTable<1> table = table_of(segs);
        const std::vector<char> none_recursive(segs.size(), 0);
        const CmCutOffs<1> cut = detail::cm_cut_offs(table, times, none_recursive);
        EXPECT_TRUE(cut.log_cells.empty());
        std::size_t kept = 0, reaching = 0;
        detail::for_each_cell(table.tau, times, 0, [&](std::size_t j, std::size_t k0, std::size_t k1) {
            const double ln_delta =
                std::min(table.log_dominance(j, times[k0])[0], table.log_dominance(j, times[k1 - 1])[0]) +
                table.ln_factor[0];
            for (std::size_t f = k0; f < k1; ++f)
                for (std::size_t i = 0; i < table.n; ++i) {
                    const bool in_hull = cut.hull_lo[i] != CmCutOffs<1>::none && cut.hull_lo[i] <= f &&
                                         f < cut.hull_hi[i];
                    kept += in_hull;
                    if (table.log_dominance(i, times[f])[0] < ln_delta) continue;
                    ++reaching;
                    EXPECT_TRUE(in_hull) << "segment " << i << " frame " << f;
                    if (in_hull) {
                        EXPECT_LE(cut.hull_ln_delta(0, static_cast<Eigen::Index>(i)), ln_delta);
                    }
                }
            return true;
        });
        EXPECT_GT(reaching, 0u);
        // The cut-offs leave segments out: far fewer (segment, frame) pairs
        // than the full sum evaluates.
        EXPECT_LT(kept, table.n * times.size() / 4);
    }
}

TEST(CmBoundedSumSteps, RecursiveSumsEqualTheDirectSumsForUnitExponent) {
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        double end_s = 0.0;
        const auto segs = random_segments(rng, 80, 3.0, 120.0, [] { return 1.0; }, end_s);
        const std::vector<double> times = frame_times(end_s, seed % 2 ? 60.0 : 90.0);
        const CmTable<1> table = table_of(segs);
        const auto step = detail::uniform_step(times);
        ASSERT_TRUE(step.has_value());
        const std::vector<char> recursive = detail::cm_recursive_segments(table, times, true);
        for (char r : recursive) ASSERT_TRUE(r);
        detail::CmFrameSums<1> num(times.size()), den(times.size());
        detail::recursive_sums<1>(times, *step, table.tau, recursive, table.theta, table.phi, table.alpha,
                                  table.target_alpha, num, den);
        double worst = 0.0;
        for (std::size_t f = 0; f < times.size(); ++f) {
            double direct_num = 0.0, direct_den = 0.0;
            for (const CmSegment& s : segs) {
                const double d = dominance(s, times[f]);
                direct_num += s.target * d;
                direct_den += d;
            }
            worst = std::max({worst, std::abs(num[f][0] - direct_num) / direct_den,
                              std::abs(den[f][0] - direct_den) / direct_den});
        }
        EXPECT_LT(worst, 1e-12);
    }
}

TEST(CmBoundedSumSteps, RecursionOnlyForUnitExponentOnUniformFramesWithoutUnderflow) {
    Rng rng(5);
    double end_s = 0.0;
    int i = 0;
    const auto segs = random_segments(rng, 40, 5.0, 60.0, [&] { return i++ % 3 == 0 ? 1.0 : 1.5; }, end_s);
    const std::vector<double> times = frame_times(end_s, 60.0);
    const CmTable<1> table = table_of(segs);
    const std::vector<char> recursive = detail::cm_recursive_segments(table, times, true);
    for (std::size_t k = 0; k < segs.size(); ++k) EXPECT_EQ(recursive[k] != 0, table.c[k] == 1.0) << k;
    // Frames not uniformly spaced: no recursion.
    for (char r : detail::cm_recursive_segments(table, times, false)) EXPECT_FALSE(r);
    // An owner whose dominance falls below e^−600 within its own cell: none.
    std::vector<CmSegment> steep = segs;
    steep[10].theta_per_s = steep[10].phi_per_s = 1e9;
    steep[10].c = 1.0;
    for (char r : detail::cm_recursive_segments(table_of(steep), times, true)) EXPECT_FALSE(r);
}

TEST(CmBoundedSumSteps, LogDomainCellsGiveTheFullSumWhereThresholdsUnderflow) {
    for (std::uint64_t seed = 1; seed <= 6; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        double end_s = 0.0;
        // Rates so steep that a segment's dominance at its cell's edge is far
        // below e^−680: absolute dominances would underflow.
        const auto segs = random_segments(rng, 30, 5e4, 2e5, [&] { return rng.uniform(0.8, 1.2); }, end_s);
        const std::vector<double> times = frame_times(end_s, 60.0);
        const CmTable<1> table = table_of(segs);
        const CmCutOffs<1> cut = detail::cm_cut_offs(table, times, std::vector<char>(segs.size(), 0));
        ASSERT_FALSE(cut.log_cells.empty());
        std::vector<double> got(times.size(), std::numeric_limits<double>::quiet_NaN());
        detail::cm_log_domain_cells(table, times, cut.log_cells,
                                    [&](std::size_t f, std::size_t p, double z) {
                                        EXPECT_EQ(p, 0u);
                                        got[f] = z;
                                    });
        const std::vector<double> full = full_sum(segs, times);
        std::size_t given = 0;
        for (const auto& cell : cut.log_cells)
            for (std::size_t f = cell.k0; f < cell.k; ++f) {
                ASSERT_TRUE(std::isfinite(got[f])) << f;
                EXPECT_NEAR(got[f], full[f], 1e-9) << f;
                ++given;
            }
        EXPECT_GT(given, 0u);
    }
}

TEST(CmBoundedSumSteps, BlockAccumulationMatchesTheFullSumAcrossBlockEdges) {
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        Rng rng(seed);
        double end_s = 0.0;
        // c = 1 for every other segment: on uniform frames those go through
        // the recurrence inside a block, on jittered frames through the kernel.
        int i = 0;
        const auto segs = random_segments(rng, 120, 3.0, 120.0,
                                          [&] { return i++ % 2 ? 1.0 : rng.uniform(0.5, 2.5); }, end_s);
        std::vector<double> times = frame_times(end_s, 60.0);
        ASSERT_GT(times.size(), 2 * 256u);  // crosses block edges
        if (seed % 2 == 0)
            for (std::size_t k = 1; k < times.size(); ++k) times[k] += rng.uniform(0.0, 0.002);
        const auto step = detail::uniform_step(times);
        EXPECT_EQ(step.has_value(), seed % 2 == 1);
        const CmTable<1> table = table_of(segs);
        const CmCutOffs<1> cut = detail::cm_cut_offs(table, times, std::vector<char>(segs.size(), 0));
        ASSERT_TRUE(cut.log_cells.empty());
        std::vector<double> got(times.size(), std::numeric_limits<double>::quiet_NaN());
        detail::CmBlockScratch<1> scratch;
        detail::cm_accumulate_blocks<1>(table, times, step, cut, nullptr, nullptr, scratch,
                                        [&](std::size_t f, std::size_t, double z) { got[f] = z; });
        const std::vector<double> full = full_sum(segs, times);
        double worst = 0.0;
        for (std::size_t f = 0; f < times.size(); ++f) worst = std::max(worst, std::abs(got[f] - full[f]));
        EXPECT_LE(worst, 1e-9);
    }
}

}  // namespace
}  // namespace avsi::synth
