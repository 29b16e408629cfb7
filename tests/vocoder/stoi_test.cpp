// STOI/ESTOI against the published reference values of the torchmetrics /
// pystoi test pair (read from ../shared/testdata/stoi, skipped when absent),
// identity, and monotonic behaviour with added noise.
#include "avsi/vocoder/stoi.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "avsi/core/audio.h"
#include "avsi/core/error.h"
#include "avsi/core/rng.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

const std::filesystem::path kStoiDir = std::filesystem::path(AVSI_SHARED_DIR) / "testdata" / "stoi";

TEST(Stoi, ReferencePairMatchesPublishedValues) {
    const auto clean_path = kStoiDir / "audio_speech.wav";
    const auto noisy_path = kStoiDir / "audio_speech_bab_0dB.wav";
    if (!std::filesystem::exists(clean_path) || !std::filesystem::exists(noisy_path))
        GTEST_SKIP() << "reference pair not found in " << kStoiDir;
    const Audio clean = read_audio(clean_path);
    const Audio noisy = read_audio(noisy_path);
    ASSERT_EQ(clean.sample_rate_hz, 16000);
    // Reference: MATLAB stoi.m 0.6739 (pystoi 0.4.1: 0.6739177895).
    EXPECT_NEAR(stoi(clean, noisy), 0.6739, 0.001);
    // Reference: pystoi 0.4.1 extended=True: 0.3904499910.
    EXPECT_NEAR(stoi(clean, noisy, {.extended = true}), 0.3904, 0.002);
}

TEST(Stoi, IdenticalSignalsScoreOne) {
    const auto x = testing::speech_like(16000, 2.0);
    EXPECT_NEAR(stoi(x, x, 16000), 1.0, 1e-9);
    EXPECT_NEAR(stoi(x, x, 16000, {.extended = true}), 1.0, 1e-9);
    const auto y = testing::speech_like(10000, 2.0);  // no resampling
    EXPECT_NEAR(stoi(y, y, 10000), 1.0, 1e-9);
}

TEST(Stoi, FallsAsNoiseRises) {
    const auto x = testing::speech_like(16000, 3.0);
    const double speech_rms = testing::rms(x);
    for (bool extended : {false, true}) {
        SCOPED_TRACE(extended);
        double previous = 1.0;
        for (double snr_db : {20.0, 5.0, -5.0, -15.0}) {
            Rng rng(11);
            std::vector<double> y = x;
            const double noise_rms = speech_rms * std::pow(10.0, -snr_db / 20.0);
            for (double& v : y) v += noise_rms * rng.normal();
            const double d = stoi(x, y, 16000, {.extended = extended});
            EXPECT_LT(d, previous) << "at " << snr_db << " dB SNR";
            previous = d;
        }
    }
}

TEST(Stoi, RefusesMismatchedOrTooShortInput) {
    const std::vector<double> a(16000, 0.1), b(15999, 0.1);
    EXPECT_THROW(stoi(a, b, 16000), InputError);
    const auto short_x = testing::speech_like(16000, 0.2);
    EXPECT_THROW(stoi(short_x, short_x, 16000), InputError);
}

}  // namespace
}  // namespace avsi::vocoder
