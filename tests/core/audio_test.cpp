#include "avsi/core/audio.h"

#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

Audio make_tone(int rate, int channels, double seconds) {
    Audio a;
    a.sample_rate_hz = rate;
    a.channels = channels;
    const auto frames = static_cast<std::size_t>(rate * seconds);
    a.samples.resize(frames * channels);
    for (std::size_t i = 0; i < frames; ++i)
        for (int c = 0; c < channels; ++c)
            a.samples[i * channels + c] = static_cast<float>(
                0.8 * std::sin(2 * std::numbers::pi * (440.0 + 110.0 * c) * double(i) / rate));
    return a;
}

struct Case {
    int rate;
    int channels;
    SampleFormat format;
    const char* ext;
    double tolerance;
};

class AudioRoundTrip : public ::testing::TestWithParam<Case> {};

TEST_P(AudioRoundTrip, ReadsBackWhatWasWritten) {
    const Case c = GetParam();
    const fs::path path = fs::temp_directory_path() /
                          ("avsi_audio_" + std::to_string(::getpid()) + "_" + std::to_string(c.rate) +
                           "_" + std::to_string(static_cast<int>(c.format)) + c.ext);
    const Audio in = make_tone(c.rate, c.channels, 0.25);
    write_audio(path, in, c.format);
    const Audio out = read_audio(path);
    EXPECT_EQ(out.sample_rate_hz, c.rate);
    EXPECT_EQ(out.channels, c.channels);
    ASSERT_EQ(out.samples.size(), in.samples.size());
    double max_err = 0;
    for (std::size_t i = 0; i < in.samples.size(); ++i)
        max_err = std::max(max_err, double(std::abs(in.samples[i] - out.samples[i])));
    EXPECT_LE(max_err, c.tolerance);
    fs::remove(path);
}

INSTANTIATE_TEST_SUITE_P(
    FormatsAndRates, AudioRoundTrip,
    ::testing::Values(Case{8000, 1, SampleFormat::Pcm16, ".wav", 1.0 / 32768},
                      Case{16000, 1, SampleFormat::Pcm24, ".wav", 1.0 / 8388608},
                      Case{22050, 2, SampleFormat::Float32, ".wav", 0.0},
                      Case{44100, 1, SampleFormat::Pcm16, ".wav", 1.0 / 32768},
                      Case{48000, 2, SampleFormat::Pcm24, ".wav", 1.0 / 8388608},
                      Case{11025, 1, SampleFormat::Float32, ".wav", 0.0},
                      Case{16000, 1, SampleFormat::Pcm16, ".flac", 1.0 / 32768},
                      Case{48000, 2, SampleFormat::Pcm24, ".flac", 1.0 / 8388608}));

TEST(Audio, MonoAveragesChannels) {
    Audio a{8000, 2, {1.0f, 0.0f, 0.5f, -0.5f}};
    EXPECT_EQ(a.frames(), 2u);
    EXPECT_EQ(a.mono(), (std::vector<float>{0.5f, 0.0f}));
    EXPECT_EQ(a.channel(1), (std::vector<float>{0.0f, -0.5f}));
}

TEST(Audio, UnreadableFilesAreInputErrorsNamingTheFile) {
    const fs::path bogus = fs::temp_directory_path() / (std::to_string(::getpid()) + "_avsi_not_audio.wav");
    write_text_file(bogus, "this is not a wav file");
    try {
        read_audio(bogus);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, bogus.string());
    }
    EXPECT_THROW(read_audio("/nonexistent/x.wav"), InputError);
    EXPECT_THROW(write_audio(fs::temp_directory_path() / (std::to_string(::getpid()) + "_x.mp3"), Audio{8000, 1, {0.0f}}), InputError);
    fs::remove(bogus);
}

}  // namespace
}  // namespace avsi
