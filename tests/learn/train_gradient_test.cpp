// Gradient checks of the training Jacobians (Beskow eq. 9–14 Cohen-Massaro,
// eq. 18–20 Öhman, summed per phone class) against central finite
// differences at random parameter points. (Training differentiates the
// models' own forward passes, cohen_massaro.h and ohman.h, so there is no
// second forward pass to compare with the models'.)
#include <gtest/gtest.h>

#include <cmath>

#include "avsi/core/rng.h"
#include "avsi/learn/training.h"
#include "avsi/synth/cohen_massaro.h"

using namespace avsi;
using namespace avsi::synth;
using namespace avsi::learn;

namespace {

// Random utterance of `n` segments over `keys` phone keys; anchors are keys < 2.
KeyedUtterance random_utterance(Rng& rng, int n, int keys) {
    KeyedUtterance u;
    double t = 0.0;
    for (int i = 0; i < n; ++i) {
        const double d = rng.uniform(0.04, 0.2);
        u.centres_s.push_back(t + d / 2);
        t += d;
        const int key = static_cast<int>(rng.uniform_int(static_cast<std::uint64_t>(keys)));
        u.key.push_back(key);
        u.anchor.push_back(key < 2);
    }
    for (double s = 0.0; s < t; s += 1.0 / 60.0) u.times_s.push_back(s + rng.uniform(0.0, 0.001));
    return u;
}

using Keyed = void (*)(const KeyedUtterance&, std::span<const double>, std::vector<double>&, std::vector<double>*);

// Max over entries of |analytic − numeric| / max(|analytic|, |numeric|), for
// entries above an absolute floor where relative error is meaningful.
void check_gradient(Keyed f, const KeyedUtterance& u, std::vector<double> x, const char* what) {
    std::vector<double> z, jac, zp, zm;
    f(u, x, z, &jac);
    const std::size_t cols = x.size();
    double worst = 0.0;
    // Central differences with Richardson extrapolation (error O(h⁴)).
    auto central = [&](std::size_t j, double h, std::vector<double>& d) {
        const double keep = x[j];
        x[j] = keep + h;
        f(u, x, zp, nullptr);
        x[j] = keep - h;
        f(u, x, zm, nullptr);
        x[j] = keep;
        d.resize(zp.size());
        for (std::size_t k = 0; k < zp.size(); ++k) d[k] = (zp[k] - zm[k]) / (2 * h);
    };
    std::vector<double> d1, d2;
    for (std::size_t j = 0; j < cols; ++j) {
        const double h = 1e-4 * std::max(1.0, std::abs(x[j]));
        central(j, h, d1);
        central(j, h / 2, d2);
        for (std::size_t k = 0; k < z.size(); ++k) {
            const double numeric = (4 * d2[k] - d1[k]) / 3;
            const double analytic = jac[k * cols + j];
            // Relative error; entries below 1e-3 (in units of z per unit x)
            // are held to the same 1e-6 against a 1e-3 scale.
            const double scale = std::max({std::abs(numeric), std::abs(analytic), 1e-3});
            worst = std::max(worst, std::abs(numeric - analytic) / scale);
        }
    }
    EXPECT_LT(worst, 1e-6) << what;
}

}  // namespace

TEST(TrainGradient, CohenMassaroAnalyticMatchesCentralDifferences) {
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
        SCOPED_TRACE(seed);
        Rng rng(seed);
        const int keys = 5;
        const KeyedUtterance u = random_utterance(rng, 12, keys);
        std::vector<double> x;
        for (int k = 0; k < keys; ++k) {
            x.push_back(rng.uniform(-0.5, 1.0));  // T
            x.push_back(rng.uniform(0.2, 5.0));   // α
            x.push_back(rng.uniform(5.0, 60.0));  // θ
            x.push_back(rng.uniform(5.0, 60.0));  // φ
            x.push_back(rng.uniform(0.6, 2.0));   // c
        }
        check_gradient(cohen_massaro_keyed, u, x, "cohen-massaro");
    }
}

TEST(TrainGradient, OhmanAnalyticMatchesCentralDifferences) {
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
        SCOPED_TRACE(seed);
        Rng rng(seed);
        const int keys = 6;
        const KeyedUtterance u = random_utterance(rng, 14, keys);
        std::vector<double> x;
        for (int k = 0; k < keys; ++k) {
            x.push_back(rng.uniform(-0.5, 1.0));                 // a or c
            x.push_back(k < 2 ? 0.0 : rng.uniform(0.05, 0.95));  // w_c
        }
        check_gradient(ohman_keyed, u, x, "ohman");
    }
}

TEST(TrainGradient, CohenMassaroSkipsFarSegmentsWithoutChangingTheResult) {
    // Fast dominance decay over a long utterance: most segments are left out
    // at each frame, yet z matches the full sum and the gradient still checks.
    for (std::uint64_t seed = 21; seed <= 23; ++seed) {
        SCOPED_TRACE(seed);
        Rng rng(seed);
        const int keys = 6;
        const KeyedUtterance u = random_utterance(rng, 40, keys);
        std::vector<double> x;
        for (int k = 0; k < keys; ++k)
            for (double v : {rng.uniform(-0.5, 1.0), rng.uniform(0.2, 5.0), rng.uniform(60.0, 300.0),
                             rng.uniform(60.0, 300.0), rng.uniform(0.8, 1.5)})
                x.push_back(v);
        std::vector<CmSegment> segs;
        for (std::size_t i = 0; i < u.centres_s.size(); ++i) {
            const double* q = x.data() + 5 * u.key[i];
            segs.push_back({u.centres_s[i], q[0], q[1], q[2], q[3], q[4]});
        }
        std::vector<double> z;
        CmPartials partials;
        cohen_massaro_partials(segs, u.times_s, z, &partials);
        std::size_t kept = 0;
        for (std::size_t k = 0; k < z.size(); ++k) kept += partials.row_start[k + 1] - partials.row_start[k];
        EXPECT_LT(kept, z.size() * segs.size() / 2);  // the bound does leave segments out
        std::vector<double> reference(u.times_s.size());
        cohen_massaro_full(segs, u.times_s, reference);
        for (std::size_t k = 0; k < z.size(); ++k) EXPECT_NEAR(z[k], reference[k], 1e-12);
        check_gradient(cohen_massaro_keyed, u, x, "cohen-massaro, far segments skipped");
    }
}
