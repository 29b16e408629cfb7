// Masking noise: the SNR achieved, the active-frame reference, the shape of
// speech-shaped noise, and determinism by seed.
#include "avsi/vocoder/masking.h"

#include <gtest/gtest.h>

#include <cmath>

#include "avsi/core/rng.h"
#include "avsi/vocoder/filters.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

Audio to_audio(const std::vector<double>& x, int rate) {
    Audio a;
    a.sample_rate_hz = rate;
    a.samples.assign(x.begin(), x.end());
    return a;
}

double band_db(std::vector<double> x, double lo, double hi, double rate) {
    sos_filter(butterworth_bandpass(4, lo, hi, rate), x);
    return 20.0 * std::log10(testing::rms(x));
}

TEST(Masking, MixReachesTheRequestedSnr) {
    const int rate = 16000;
    const auto speech = testing::speech_like(rate, 2.0);
    Rng rng(4);
    std::vector<double> noise(rate * 5);
    for (double& v : noise) v = rng.normal();
    for (double snr : {-10.0, 0.0, 12.5}) {
        SCOPED_TRACE(snr);
        const auto mixed = mix_at_snr(to_audio(speech, rate), noise, {.snr_db = snr});
        std::vector<double> added(speech.size());
        for (std::size_t i = 0; i < speech.size(); ++i) added[i] = double(mixed.audio.samples[i]) - float(speech[i]);
        EXPECT_NEAR(20.0 * std::log10(testing::rms(speech) / testing::rms(added)), snr, 0.01);
        EXPECT_NEAR(20.0 * std::log10(mixed.speech_rms / mixed.noise_rms), snr, 1e-9);
    }
}

TEST(Masking, ActiveFramesExcludePauses) {
    const int rate = 16000;
    auto speech = testing::speech_like(rate, 1.0);
    const std::size_t n = speech.size();
    speech.resize(3 * n, 0.0);  // two thirds silence
    const double whole = speech_level_rms(speech, rate, SnrReference::WholeSignal);
    const double active = speech_level_rms(speech, rate, SnrReference::ActiveFrames);
    // The 4 Hz syllable envelope also has low frames, so active > whole·√3 is the bound.
    EXPECT_GT(20.0 * std::log10(active / whole), 10.0 * std::log10(3.0) - 0.1);
}

TEST(Masking, SpeechShapedNoiseFollowsTheLongTermSpectrum) {
    const int rate = 16000;
    const auto speech = testing::speech_like(rate, 4.0);
    const LongTermSpectrum ltas = long_term_spectrum({to_audio(speech, rate)});
    const auto noise = speech_shaped_noise(ltas, speech.size(), rate, 3);
    EXPECT_NEAR(testing::rms(noise), 1.0, 1e-9);
    // Relative band levels agree (speech scaled to unit RMS).
    const double scale_db = -20.0 * std::log10(testing::rms(speech));
    for (auto [lo, hi] : {std::pair{200.0, 400.0}, {400.0, 800.0}, {800.0, 1600.0}, {1600.0, 3200.0}}) {
        SCOPED_TRACE(lo);
        EXPECT_NEAR(band_db(noise, lo, hi, rate), band_db(speech, lo, hi, rate) + scale_db, 2.0);
    }
    EXPECT_EQ(speech_shaped_noise(ltas, 1000, rate, 3), speech_shaped_noise(ltas, 1000, rate, 3));
    EXPECT_NE(speech_shaped_noise(ltas, 1000, rate, 3), speech_shaped_noise(ltas, 1000, rate, 4));
}

TEST(Masking, ShortNoiseIsLoopedAndLongNoiseExcerptedBySeed) {
    const int rate = 8000;
    const auto speech = testing::speech_like(rate, 1.0);
    std::vector<double> short_noise = {0.5, -0.5, 0.25};
    EXPECT_NO_THROW(mix_at_snr(to_audio(speech, rate), short_noise, {}));
    Rng rng(1);
    std::vector<double> long_noise(rate * 10);
    for (double& v : long_noise) v = rng.normal();
    const auto a = mix_at_snr(to_audio(speech, rate), long_noise, {.seed = 1});
    const auto b = mix_at_snr(to_audio(speech, rate), long_noise, {.seed = 1});
    const auto c = mix_at_snr(to_audio(speech, rate), long_noise, {.seed = 2});
    EXPECT_EQ(a.audio.samples, b.audio.samples);
    EXPECT_NE(a.audio.samples, c.audio.samples);
}

}  // namespace
}  // namespace avsi::vocoder
