// Gradient checks of the training Jacobians (Beskow eq. 9–14 Cohen-Massaro,
// eq. 18–20 Öhman, summed per phone class) against central finite
// differences at random parameter points, and agreement of the training
// forward passes with the models' own evaluation.
#include <gtest/gtest.h>

#include <cmath>

#include "avsi/core/rng.h"
#include "avsi/synth/cohen_massaro.h"
#include "avsi/synth/ohman.h"
#include "avsi/synth/training.h"

using namespace avsi;
using namespace avsi::synth;

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

TEST(TrainGradient, CohenMassaroForwardMatchesTheModelsFullSum) {
    Rng rng(11);
    const KeyedUtterance u = random_utterance(rng, 15, 4);
    std::vector<double> x;
    for (int k = 0; k < 4; ++k)
        for (double v : {rng.uniform(-0.5, 1.0), rng.uniform(0.2, 5.0), rng.uniform(5.0, 60.0), rng.uniform(5.0, 60.0),
                         rng.uniform(0.6, 2.0)})
            x.push_back(v);
    std::vector<double> z;
    cohen_massaro_keyed(u, x, z, nullptr);
    std::vector<CmSegment> segs;
    for (std::size_t i = 0; i < u.centres_s.size(); ++i) {
        const double* q = x.data() + 5 * u.key[i];
        segs.push_back({u.centres_s[i], q[0], q[1], q[2], q[3], q[4]});
    }
    std::vector<double> reference(u.times_s.size());
    cohen_massaro_full(segs, u.times_s, reference);
    for (std::size_t k = 0; k < z.size(); ++k) EXPECT_NEAR(z[k], reference[k], 1e-12);
}

TEST(TrainGradient, OhmanForwardMatchesTheModel) {
    // sil AA1 P T IY0 M sil as keys 0..; the model holds the same numbers.
    const PhoneSequence phones{{"sil", 0, 0.1}, {"AA", 0.1, 0.25, true}, {"P", 0.25, 0.3}, {"T", 0.3, 0.38},
                               {"IY", 0.38, 0.5, false}, {"M", 0.5, 0.58}, {"sil", 0.58, 0.7}};
    OhmanModel::VowelTable vowels;
    OhmanModel::ConsonantTable consonants;
    const std::vector<double> x = {0.05, 0, 0.8, 0, 0.1, 0.9, 0.3, 0.4, 0.25, 0, 0.05, 0.7};
    auto frame = [](double v) { Frame f{}; f[index(Param::JawRotation)] = v; return f; };
    vowels["sil"] = frame(x[0]);
    vowels["AA1"] = frame(x[2]);
    vowels["IY0"] = frame(x[8]);
    auto cons = [](double c, double w) { OhmanConsonant o{}; o[index(Param::JawRotation)] = {c, w}; return o; };
    consonants["P"] = cons(x[4], x[5]);
    consonants["T"] = cons(x[6], x[7]);
    consonants["M"] = cons(x[10], x[11]);
    const OhmanModel model(vowels, consonants);
    KeyedUtterance u;
    const std::vector<int> keys = {0, 1, 2, 3, 4, 5, 0};
    for (std::size_t i = 0; i < phones.size(); ++i) {
        u.centres_s.push_back(phones[i].centre_s());
        u.key.push_back(keys[i]);
        u.anchor.push_back(i == 0 || i == 1 || i == 4 || i == 6);
    }
    for (double t = 0; t < 0.7; t += 0.005) u.times_s.push_back(t);
    std::vector<double> z;
    ohman_keyed(u, x, z, nullptr);
    std::vector<Frame> reference;
    model.evaluate(phones, u.times_s, reference);
    for (std::size_t k = 0; k < z.size(); ++k)
        EXPECT_NEAR(z[k], reference[k][index(Param::JawRotation)], 1e-12) << u.times_s[k];
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
