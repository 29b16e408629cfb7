// Audio buffers and WAV/FLAC file I/O through libsndfile.
#pragma once

#include <cstddef>
#include <filesystem>
#include <vector>

namespace avsi {

// Float samples in [-1, 1], interleaved when there is more than one channel.
struct Audio {
    int sample_rate_hz = 0;
    int channels = 1;
    std::vector<float> samples;

    std::size_t frames() const { return channels > 0 ? samples.size() / channels : 0; }
    double duration_s() const {
        return sample_rate_hz > 0 ? static_cast<double>(frames()) / sample_rate_hz : 0.0;
    }
    // One channel, de-interleaved.
    std::vector<float> channel(int index) const;
    // The mean of all channels.
    std::vector<float> mono() const;
};

// Sample encodings avsi writes.
enum class SampleFormat { Pcm16, Pcm24, Float32 };

// Reads any WAV or FLAC file libsndfile can read (any rate, 1 or more channels).
// Throws InputError naming the file on failure, and for a float file with a
// sample that is not a finite number (a NaN or an infinity: every level,
// filter and score computed from it would be one too).
Audio read_audio(const std::filesystem::path& path);

// Throws that InputError for the first non-finite value of `count`
// interleaved samples of `channels` channels at `rate_hz`, the first of
// which is frame `first_frame` of `path`.
void require_finite_samples(const std::filesystem::path& path, const float* samples, std::size_t count,
                            int channels, int rate_hz, std::size_t first_frame);

// Writes WAV (.wav) or FLAC (.flac, PCM only) by the file extension. The file
// is written beside the target and renamed into place, so an existing file is
// never left half-written.
void write_audio(const std::filesystem::path& path, const Audio& audio,
                 SampleFormat format = SampleFormat::Pcm16);

}  // namespace avsi
