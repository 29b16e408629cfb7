#include "avsi/core/audio.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include "avsi/core/audio_stream.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

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
    const fs::path path = test::temp_dir("audio_roundtrip") /
                          (std::to_string(c.rate) + "_" + std::to_string(static_cast<int>(c.format)) + c.ext);
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
    const fs::path dir = test::temp_dir("audio_unreadable");
    const fs::path bogus = dir / "not_audio.wav";
    write_text_file(bogus, "this is not a wav file");
    try {
        read_audio(bogus);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, bogus.string());
    }
    EXPECT_THROW(read_audio("/nonexistent/x.wav"), InputError);
    EXPECT_THROW(write_audio(dir / "x.mp3", Audio{8000, 1, {0.0f}}), InputError);
    fs::remove(bogus);
}

// A WAV cut short (a copy that stopped) is refused by both readers, naming
// both lengths (libsndfile reads what is there and says so only in its
// log); a WAV whose sizes are the 0xFFFFFFFF placeholder of a writer that
// could not go back to fill them in reads.
TEST(Audio, TruncatedWavIsRefusedNamingBothLengths) {
    const fs::path dir = test::temp_dir("audio_truncated");
    const fs::path whole = dir / "whole.wav", cut = dir / "cut.wav";
    write_audio(whole, make_tone(16000, 1, 1.0));
    const std::string bytes = read_text_file(whole);  // 44-byte header, 32000 bytes of samples
    write_text_file(cut, bytes.substr(0, 44 + 8000));
    const std::string expected = "its header declares 32000 bytes of audio, the file holds 8000 (0.25 s of 1.00 s)";
    try {
        read_audio(cut);
        ADD_FAILURE() << "read_audio accepted a truncated file";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, cut.string());
        EXPECT_NE(e.first().message.find(expected), std::string::npos) << e.first().message;
    }
    try {
        AudioFileReader reader(cut);
        ADD_FAILURE() << "AudioFileReader accepted a truncated file";
    } catch (const InputError& e) {
        EXPECT_NE(e.first().message.find(expected), std::string::npos) << e.first().message;
    }
    std::string placeholder = bytes;
    const std::size_t data = placeholder.find("data");
    ASSERT_NE(data, std::string::npos);
    for (std::size_t at : {std::size_t{4}, data + 4}) placeholder.replace(at, 4, "\xff\xff\xff\xff");
    write_text_file(cut, placeholder);
    EXPECT_EQ(read_audio(cut).frames(), 16000u);
    EXPECT_EQ(AudioFileReader(cut).frames(), 16000u);
    fs::remove(whole);
    fs::remove(cut);
}

// A float file with a NaN or an infinity is refused, by the whole-file
// reader and the block reader alike, naming the frame and the channel (a
// vocoder run on it wrote a file of full-scale negative samples).
TEST(Audio, FloatFilesWithNonFiniteSamplesAreRefusedNamingTheSample) {
    const fs::path path = test::temp_dir("audio_nonfinite") / "nonfinite.wav";
    for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity()}) {
        Audio a = make_tone(8000, 2, 1.0);
        a.samples[5000 * 2 + 1] = bad;  // frame 5000, channel 2
        write_audio(path, a, SampleFormat::Float32);
        try {
            read_audio(path);
            ADD_FAILURE() << "read_audio accepted " << bad;
        } catch (const InputError& e) {
            EXPECT_EQ(e.first().path, path.string());
            EXPECT_EQ(e.first().field, "samples");
            EXPECT_NE(e.first().message.find("frame 5000 (0.625000 s), channel 2"), std::string::npos)
                << e.first().message;
        }
        AudioFileReader reader(path);
        std::vector<float> block(999 * 2);
        std::size_t read = 0;
        try {
            while (const std::size_t n = reader.read(block.data(), 999)) read += n;
            ADD_FAILURE() << "AudioFileReader accepted " << bad;
        } catch (const InputError& e) {
            EXPECT_EQ(read, 4995u);  // the blocks before the one that holds it
            EXPECT_NE(e.first().message.find("frame 5000 (0.625000 s), channel 2"), std::string::npos)
                << e.first().message;
        }
    }
    // The same value in 16-bit PCM is a full-scale sample, and reads.
    Audio a = make_tone(8000, 1, 0.5);
    a.samples[100] = std::numeric_limits<float>::infinity();
    write_audio(path, a, SampleFormat::Pcm16);
    EXPECT_NO_THROW(read_audio(path));
    fs::remove(path);
}

// 16-bit samples made here (float_to_pcm16, then write_pcm16) give the same
// file, byte for byte, as libsndfile's own conversion (write): on every
// 16-bit step and half step of [-1.01, 1.01] with six float steps either
// side, 5 million uniform values in [-1.2, 1.2] and the extremes,
// infinities and NaN; in one channel and in two.
TEST(AudioStream, SixteenBitSamplesMadeHereGiveLibsndfilesFile) {
    std::vector<float> values;
    for (int k = -33100; k <= 33100; ++k) {
        for (double at : {k / 32768.0, (k + 0.5) / 32768.0}) {
            float up = static_cast<float>(at), down = up;
            values.push_back(up);
            for (int i = 0; i < 6; ++i) {
                values.push_back(up = std::nextafter(up, 2.0f));
                values.push_back(down = std::nextafter(down, -2.0f));
            }
        }
    }
    std::mt19937 random(3);
    std::uniform_real_distribution<float> uniform(-1.2f, 1.2f);
    for (int i = 0; i < 5'000'000; ++i) values.push_back(uniform(random));
    for (float x : {0.0f, -0.0f, std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                    std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                    std::numeric_limits<float>::quiet_NaN(), -std::numeric_limits<float>::quiet_NaN(),
                    std::numeric_limits<float>::denorm_min(), 1e-30f, -1e-30f})
        values.push_back(x);
    values.resize(values.size() / 2 * 2);  // whole stereo frames
    // Converted in uneven pieces, so that both the eight-at-a-time loop and
    // the one-at-a-time rest see many values.
    std::vector<std::int16_t> converted(values.size());
    for (std::size_t done = 0, piece = 1; done < values.size(); done += piece, piece = piece % 29 + 1)
        float_to_pcm16(values.data() + done, std::min(piece, values.size() - done), converted.data() + done);
    for (int channels : {1, 2}) {
        SCOPED_TRACE(channels);
        const std::size_t frames = values.size() / static_cast<std::size_t>(channels);
        const fs::path dir = test::temp_dir("audio_pcm16");
        const fs::path theirs = dir / "libsndfile.wav", ours = dir / "ours.wav";
        {
            AudioFileWriter out(theirs, 22050, channels);
            out.write(values.data(), frames);
            out.commit();
        }
        {
            AudioFileWriter out(ours, 22050, channels);
            ASSERT_TRUE(out.takes_pcm16());
            // In uneven pieces, as a caller's blocks may be.
            std::size_t done = 0;
            for (std::size_t piece = 1; done < frames; piece = piece * 3 + 1) {
                const std::size_t n = std::min(piece, frames - done);
                out.write_pcm16(converted.data() + done * static_cast<std::size_t>(channels), n);
                done += n;
            }
            out.commit();
        }
        EXPECT_EQ(read_text_file(ours), read_text_file(theirs));
        fs::remove(ours);
        fs::remove(theirs);
    }
}

// Only a 16-bit WAV takes ready-made 16-bit samples.
TEST(AudioStream, OnlySixteenBitWavTakesSixteenBitSamples) {
    const fs::path dir = test::temp_dir("audio_takes");
    const std::string stem = "takes";
    struct Kind {
        const char* ext;
        SampleFormat format;
        bool takes;
    };
    for (const Kind& k : {Kind{".wav", SampleFormat::Pcm16, true}, Kind{".wav", SampleFormat::Pcm24, false},
                          Kind{".wav", SampleFormat::Float32, false}, Kind{".flac", SampleFormat::Pcm16, false}}) {
        SCOPED_TRACE(std::string(k.ext) + " " + std::to_string(static_cast<int>(k.format)));
        AudioFileWriter out(dir / (stem + k.ext), 16000, 1, k.format);
        EXPECT_EQ(out.takes_pcm16(), k.takes);
    }
    Audio buffer;
    EXPECT_FALSE(AudioBufferSink(buffer).takes_pcm16());
}

// A 16-bit WAV gives its 16-bit samples, each s with read()'s float
// exactly s / 32768: every value from -32768 to 32767, in one channel and
// in two, read in uneven pieces both ways; the other files give floats only.
TEST(AudioStream, SixteenBitWavGivesSamplesWhoseFloatsAreThemOver32768) {
    std::vector<std::int16_t> every;
    for (int v = -32768; v <= 32767; ++v) every.push_back(static_cast<std::int16_t>(v));
    for (int channels : {1, 2}) {
        SCOPED_TRACE(channels);
        const fs::path path = test::temp_dir("audio_gives") / (std::to_string(channels) + ".wav");
        const std::size_t frames = every.size() / static_cast<std::size_t>(channels);
        {
            AudioFileWriter out(path, 16000, channels);
            ASSERT_TRUE(out.takes_pcm16());
            out.write_pcm16(every.data(), frames);
            out.commit();
        }
        AudioFileReader floats(path), shorts(path);
        ASSERT_TRUE(shorts.gives_pcm16());
        std::vector<float> f(every.size());
        std::vector<std::int16_t> s(every.size());
        std::size_t done_f = 0, done_s = 0;
        for (std::size_t piece = 1; done_f < frames; piece = piece * 3 + 1)
            done_f += floats.read(f.data() + done_f * channels, std::min(piece, frames - done_f));
        for (std::size_t piece = 2; done_s < frames; piece = piece * 5 + 3)
            done_s += shorts.read_pcm16(s.data() + done_s * channels, std::min(piece, frames - done_s));
        EXPECT_EQ(shorts.read_pcm16(s.data(), 1), 0u);  // at the end
        EXPECT_EQ(s, every);
        std::size_t differing = 0;
        for (std::size_t i = 0; i < every.size(); ++i) differing += f[i] != static_cast<float>(s[i] / 32768.0);
        EXPECT_EQ(differing, 0u);
        fs::remove(path);
    }
    const fs::path dir = test::temp_dir("audio_gives");
    const std::string stem = "gives";
    for (auto [ext, format] : {std::pair{".wav", SampleFormat::Pcm24}, std::pair{".wav", SampleFormat::Float32},
                               std::pair{".flac", SampleFormat::Pcm16}}) {
        const fs::path path = dir / (stem + ext);
        {
            AudioFileWriter out(path, 16000, 1, format);
            const float half = 0.5f;
            out.write(&half, 1);
            out.commit();
        }
        EXPECT_FALSE(AudioFileReader(path).gives_pcm16()) << ext << " " << static_cast<int>(format);
        fs::remove(path);
    }
    Audio buffer;
    buffer.sample_rate_hz = 16000;
    buffer.channels = 1;
    buffer.samples = {0.5f};
    EXPECT_FALSE(AudioBufferSource(buffer).gives_pcm16());
}

}  // namespace
}  // namespace avsi
