#include "avsi/core/rng.h"

#include <gtest/gtest.h>

#include <cmath>

namespace avsi {
namespace {

TEST(Rng, SameSeedSameStream) {
    Rng a(42), b(42), c(43);
    bool differs = false;
    for (int i = 0; i < 100; ++i) {
        const auto x = a.next_u64();
        EXPECT_EQ(x, b.next_u64());
        differs |= x != c.next_u64();
    }
    EXPECT_TRUE(differs);
}

TEST(Rng, KnownFirstValuesPinTheAlgorithm) {
    // xoshiro256** seeded by SplitMix64(0): any change to the generator changes
    // every stimulus and design, so the first outputs are pinned.
    Rng r(0);
    const std::uint64_t first = r.next_u64();
    Rng r2(0);
    EXPECT_EQ(first, r2.next_u64());
    EXPECT_EQ(first, 0x99ec5f36cb75f2b4ULL);
}

TEST(Rng, DerivedStreamsAreStableAndDistinct) {
    const Rng base(7);
    Rng a = base.derive("carrier/0"), b = base.derive("carrier/0"), c = base.derive("carrier/1");
    EXPECT_EQ(a.next_u64(), b.next_u64());
    EXPECT_NE(Rng(7).derive("carrier/0").next_u64(), c.next_u64());
}

TEST(Rng, UniformAndNormalMoments) {
    Rng r(123);
    const int n = 200000;
    double sum = 0, sum2 = 0, nsum = 0, nsum2 = 0;
    for (int i = 0; i < n; ++i) {
        const double u = r.uniform();
        ASSERT_GE(u, 0.0);
        ASSERT_LT(u, 1.0);
        sum += u;
        sum2 += u * u;
        const double z = r.normal();
        nsum += z;
        nsum2 += z * z;
    }
    EXPECT_NEAR(sum / n, 0.5, 0.005);
    EXPECT_NEAR(sum2 / n - std::pow(sum / n, 2), 1.0 / 12.0, 0.002);
    EXPECT_NEAR(nsum / n, 0.0, 0.01);
    EXPECT_NEAR(nsum2 / n, 1.0, 0.02);
}

TEST(Rng, UniformIntCoversRangeWithoutBias) {
    Rng r(5);
    std::vector<int> counts(6, 0);
    for (int i = 0; i < 60000; ++i) ++counts[r.uniform_int(6)];
    for (int c : counts) EXPECT_NEAR(c, 10000, 400);
}

}  // namespace
}  // namespace avsi
