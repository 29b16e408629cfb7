// Butterworth SOS design: -3 dB at the edges, unity gain in the pass band,
// the asymptotic slope, and the bank loop agreeing with the one-signal loop.
#include "avsi/vocoder/filters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <ostream>

#include "avsi/core/rng.h"

namespace avsi::vocoder {
namespace {

double gain_db(const Sos& sos, double f, double fs) { return 20.0 * std::log10(std::abs(sos_response(sos, f, fs))); }

struct BandCase {
    int order;
    double low_hz, high_hz, rate_hz;
};

// gtest prints a failing case by this (not as a byte dump).
void PrintTo(const BandCase& c, std::ostream* os) {
    *os << "order " << c.order << ", " << c.low_hz << "–" << c.high_hz << " Hz at " << c.rate_hz << " Hz";
}

class ButterworthBandpass : public ::testing::TestWithParam<BandCase> {};

TEST_P(ButterworthBandpass, MinusThreeDecibelsAtEdgesAndUnityAtCentre) {
    const BandCase c = GetParam();
    const Sos sos = butterworth_bandpass(c.order, c.low_hz, c.high_hz, c.rate_hz);
    ASSERT_EQ(sos.size(), static_cast<std::size_t>(c.order));
    const double minus3 = 10.0 * std::log10(0.5);
    EXPECT_NEAR(gain_db(sos, c.low_hz, c.rate_hz), minus3, 1e-6);
    EXPECT_NEAR(gain_db(sos, c.high_hz, c.rate_hz), minus3, 1e-6);
    // Unity at the digital image of the analog geometric centre.
    const double fs = c.rate_hz;
    const double wl = 2 * fs * std::tan(M_PI * c.low_hz / fs), wh = 2 * fs * std::tan(M_PI * c.high_hz / fs);
    const double centre = fs / M_PI * std::atan(std::sqrt(wl * wh) / (2 * fs));
    EXPECT_NEAR(gain_db(sos, centre, fs), 0.0, 1e-9);
    // No zero-gain gaps or peaks above unity across the band.
    for (int i = 1; i < 20; ++i) {
        const double f = c.low_hz * std::pow(c.high_hz / c.low_hz, i / 20.0);
        EXPECT_LE(gain_db(sos, f, fs), 1e-9);
        EXPECT_GE(gain_db(sos, f, fs), minus3 - 1e-6);
    }
    // Stable: every pole inside the unit circle (|a2| < 1 and |a1| < 1 + a2).
    for (const Biquad& q : sos) {
        EXPECT_LT(std::abs(q.a2), 1.0);
        EXPECT_LT(std::abs(q.a1), 1.0 + q.a2);
    }
}

INSTANTIATE_TEST_SUITE_P(Designs, ButterworthBandpass,
                         ::testing::Values(BandCase{4, 100, 588.6, 22050}, BandCase{4, 1773, 5000, 22050},
                                           BandCase{2, 300, 3000, 16000}, BandCase{3, 80, 8000, 44100},
                                           BandCase{1, 500, 1000, 8000}, BandCase{6, 100, 120, 48000},
                                           BandCase{5, 10, 23000, 48000}));

TEST(ButterworthBandpass, SkirtFallsSixDecibelsPerOctavePerOrder) {
    const double fs = 48000;
    const Sos sos = butterworth_bandpass(4, 1000, 2000, fs);
    // Far below the band the response falls 6·order dB per octave.
    const double drop = gain_db(sos, 50, fs) - gain_db(sos, 25, fs);
    EXPECT_NEAR(drop, 24.0, 0.3);
}

TEST(ButterworthLowpass, UnityAtDcAndMinusThreeAtCutoff) {
    for (int order : {1, 2, 3, 4, 7}) {
        SCOPED_TRACE(order);
        const Sos sos = butterworth_lowpass(order, 160.0, 22050.0);
        EXPECT_EQ(sos.size(), static_cast<std::size_t>((order + 1) / 2));
        EXPECT_NEAR(gain_db(sos, 0.0, 22050.0), 0.0, 1e-9);
        EXPECT_NEAR(gain_db(sos, 160.0, 22050.0), 10.0 * std::log10(0.5), 1e-6);
        EXPECT_LT(gain_db(sos, 1280.0, 22050.0), -6.0 * order * 3 + 1.0);  // three octaves up
    }
}

TEST(SosFilter, SteadyStateSineMatchesTheDesignedGain) {
    const double fs = 16000, f = 2500;
    const Sos sos = butterworth_bandpass(3, 1000, 2000, fs);
    std::vector<double> x(16000);
    for (std::size_t n = 0; n < x.size(); ++n) x[n] = std::sin(2 * M_PI * f * n / fs);
    sos_filter(sos, x);
    double peak = 0;
    for (std::size_t n = 8000; n < x.size(); ++n) peak = std::max(peak, std::abs(x[n]));
    EXPECT_NEAR(peak, std::abs(sos_response(sos, f, fs)), 2e-3);
}

TEST(SosFilter, ZeroPhaseSquaresTheMagnitudeAndKeepsThePhase) {
    const double fs = 16000, f = 1200;
    const Sos sos = butterworth_bandpass(2, 1000, 2000, fs);
    std::vector<double> x(32000);
    for (std::size_t n = 0; n < x.size(); ++n) x[n] = std::sin(2 * M_PI * f * n / fs);
    std::vector<double> y = x;
    sos_filtfilt(sos, y);
    const double g = std::norm(sos_response(sos, f, fs));
    // In the middle, y = g·x exactly in phase.
    double err = 0;
    for (std::size_t n = 12000; n < 20000; ++n) err = std::max(err, std::abs(y[n] - g * x[n]));
    EXPECT_LT(err, 1e-3);
}

TEST(SosBank, LanesMatchSeparateCascades) {
    const double fs = 22050;
    std::vector<Sos> cascades = {butterworth_bandpass(4, 100, 500, fs), butterworth_bandpass(4, 500, 1500, fs),
                                 butterworth_bandpass(4, 1500, 5000, fs), butterworth_bandpass(4, 300, 400, fs),
                                 butterworth_bandpass(4, 2000, 9000, fs)};
    const SosBank bank(cascades);
    EXPECT_EQ(bank.lanes(), 5u);
    EXPECT_EQ(bank.stride() % 4, 0u);
    Rng rng(3);
    const std::size_t frames = 5000;
    std::vector<double> x(frames);
    for (double& v : x) v = rng.normal();
    for (bool backward : {false, true}) {
        SCOPED_TRACE(backward);
        std::vector<double> data(frames * bank.stride(), 0.0);
        for (std::size_t n = 0; n < frames; ++n)
            for (std::size_t l = 0; l < bank.lanes(); ++l) data[n * bank.stride() + l] = x[n];
        bank.process(data.data(), frames, backward);
        for (std::size_t l = 0; l < cascades.size(); ++l) {
            std::vector<double> y(x.rbegin(), x.rend());
            if (!backward) y = x;
            sos_filter(cascades[l], y);
            if (backward) std::reverse(y.begin(), y.end());
            for (std::size_t n = 0; n < frames; ++n) ASSERT_NEAR(data[n * bank.stride() + l], y[n], 1e-12);
        }
    }
}

}  // namespace
}  // namespace avsi::vocoder
