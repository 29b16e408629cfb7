// Deterministic test signals for the vocoder tests.
#pragma once

#include <cmath>
#include <numbers>
#include <vector>

#include "avsi/core/rng.h"

namespace avsi::vocoder::testing {

// A speech-like signal: a glottal-pulse-like harmonic series (F0 gliding
// 100–140 Hz, 1/k amplitudes) shaped by three moving formant-like resonances
// and a syllabic 4 Hz envelope, plus a little seeded noise. Used where the
// property does not depend on real speech.
inline std::vector<double> speech_like(double rate_hz, double duration_s, std::uint64_t seed = 5) {
    const auto n = static_cast<std::size_t>(rate_hz * duration_s);
    std::vector<double> x(n);
    Rng rng(seed);
    double phase = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = static_cast<double>(i) / rate_hz;
        const double f0 = 120.0 + 20.0 * std::sin(2 * std::numbers::pi * 0.7 * t);
        phase += 2 * std::numbers::pi * f0 / rate_hz;
        const double formants[3] = {500.0 + 200.0 * std::sin(2 * std::numbers::pi * 1.3 * t),
                                    1500.0 + 400.0 * std::sin(2 * std::numbers::pi * 0.9 * t), 2500.0};
        double v = 0.0;
        for (int k = 1; k * f0 < std::min(5000.0, rate_hz / 2.0); ++k) {
            double a = 0.0;
            for (double f : formants) a += 1.0 / (1.0 + std::pow((k * f0 - f) / 120.0, 2.0));
            v += a / k * std::sin(k * phase);
        }
        const double syllable = 0.5 * (1.0 - std::cos(2 * std::numbers::pi * 4.0 * t));
        x[i] = 0.1 * syllable * v + 0.002 * rng.normal();
    }
    return x;
}

inline double rms(const std::vector<double>& x) {
    double s = 0.0;
    for (double v : x) s += v * v;
    return x.empty() ? 0.0 : std::sqrt(s / static_cast<double>(x.size()));
}

inline double correlation(const std::vector<double>& a, const std::vector<double>& b) {
    const std::size_t n = std::min(a.size(), b.size());
    double ma = 0, mb = 0;
    for (std::size_t i = 0; i < n; ++i) ma += a[i], mb += b[i];
    ma /= n;
    mb /= n;
    double sab = 0, saa = 0, sbb = 0;
    for (std::size_t i = 0; i < n; ++i) {
        sab += (a[i] - ma) * (b[i] - mb);
        saa += (a[i] - ma) * (a[i] - ma);
        sbb += (b[i] - mb) * (b[i] - mb);
    }
    return sab / std::sqrt(saa * sbb);
}

}  // namespace avsi::vocoder::testing
