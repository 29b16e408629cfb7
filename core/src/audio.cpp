#include "avsi/core/audio.h"

#include <sndfile.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "avsi/core/audio_stream.h"
#include "avsi/core/checks.h"
#include "avsi/core/error.h"
#include "sndfile_checks.h"

namespace avsi {

std::vector<float> Audio::channel(int index) const {
    AVSI_ASSERT(index >= 0 && index < channels);
    std::vector<float> out(frames());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = samples[i * channels + index];
    return out;
}

std::vector<float> Audio::mono() const {
    if (channels == 1) return samples;
    std::vector<float> out(frames());
    for (std::size_t i = 0; i < out.size(); ++i) {
        float sum = 0.0f;
        for (int c = 0; c < channels; ++c) sum += samples[i * channels + c];
        out[i] = sum / static_cast<float>(channels);
    }
    return out;
}

namespace {

// Throws InputError when `file`'s header declares more audio data than the
// file holds (a copy cut short: libsndfile then reads what is there and
// says so only in its log, as `data : <declared bytes> (should be <bytes
// present>)`). `present_frames` at `rate_hz` is what it found. The
// placeholder sizes of writers that could not go back to fill them in (0
// and 0xFFFFFFFF) pass.
void require_whole_data_chunk(const std::filesystem::path& path, SNDFILE* file, std::size_t present_frames,
                              int rate_hz) {
    std::string text(8192, '\0');
    sf_command(file, SFC_GET_LOG_INFO, text.data(), static_cast<int>(text.size()));
    const std::string_view log(text.c_str());
    constexpr std::string_view kData = "data : ", kShould = " (should be ";
    for (std::size_t at = 0; at < log.size();) {
        const std::size_t end = std::min(log.find('\n', at), log.size());
        const std::string_view line = log.substr(at, end - at);
        at = end + 1;
        if (!line.starts_with(kData)) continue;
        const std::size_t should = line.find(kShould);
        if (should == std::string_view::npos) continue;
        std::uint64_t declared = 0, present = 0;
        const std::string_view d = line.substr(kData.size(), should - kData.size());
        const std::string_view p = line.substr(should + kShould.size());
        if (std::from_chars(d.data(), d.data() + d.size(), declared).ec != std::errc() ||
            std::from_chars(p.data(), p.data() + p.size(), present).ec != std::errc())
            continue;
        if (declared == 0 || declared == 0xFFFFFFFFu || present == 0 || declared <= present) continue;
        const double seconds = static_cast<double>(present_frames) / rate_hz;
        throw InputError(path, fmt::format("audio file is truncated: its header declares {} bytes of audio, the "
                                           "file holds {} ({:.2f} s of {:.2f} s)",
                                           declared, present, seconds,
                                           seconds * static_cast<double>(declared) / static_cast<double>(present)));
    }
}

}  // namespace

SNDFILE* open_audio_file(const std::filesystem::path& path, SF_INFO& info) {
    info = SF_INFO{};
    SNDFILE* file = sf_open(path.c_str(), SFM_READ, &info);
    if (!file) {
        if (!std::filesystem::exists(path)) throw InputError(path, "cannot open audio file: no such file");
        throw InputError(path, fmt::format("cannot read audio file: {} (supported: WAV and FLAC, "
                                           "PCM or float)", sf_strerror(nullptr)));
    }
    try {
        if (info.samplerate <= 0 || info.channels <= 0 || info.frames < 0)
            throw InputError(path, "audio file has no valid sample rate or channel count");
        if (info.frames == 0) throw InputError(path, "audio file has no samples");
        require_whole_data_chunk(path, file, static_cast<std::size_t>(info.frames), info.samplerate);
    } catch (...) {
        sf_close(file);
        throw;
    }
    // Float reads of float files must not be rescaled; PCM maps to [-1, 1).
    sf_command(file, SFC_SET_NORM_FLOAT, nullptr, SF_TRUE);
    return file;
}

Audio read_audio(const std::filesystem::path& path) {
    SF_INFO info;
    SNDFILE* file = open_audio_file(path, info);
    struct Closer {
        SNDFILE* file;
        ~Closer() { sf_close(file); }
    } closer{file};
    // The header's length is allocated at once: bounded first (a FLAC header
    // may claim 2^36 frames in a few bytes).
    if (static_cast<std::uint64_t>(info.frames) > max_declared_count / static_cast<std::uint64_t>(info.channels))
        throw InputError(path.string(), 0, 0, "frames",
                         fmt::format("expected at most {} samples in all channels, got a header declaring {} frames of {} channels",
                                     max_declared_count, info.frames, info.channels));
    Audio audio;
    audio.sample_rate_hz = info.samplerate;
    audio.channels = info.channels;
    audio.samples.resize(static_cast<std::size_t>(info.frames) * static_cast<std::size_t>(info.channels));
    const sf_count_t read = sf_readf_float(file, audio.samples.data(), info.frames);
    if (read != info.frames)
        throw InputError(path, fmt::format("audio file is truncated: header says {} frames, read {}",
                                           info.frames, read));
    if (has_float_samples(info))
        require_finite_samples(path, audio.samples.data(), audio.samples.size(), info.channels, info.samplerate, 0);
    return audio;
}

void require_finite_samples(const std::filesystem::path& path, const float* samples, std::size_t count,
                            int channels, int rate_hz, std::size_t first_frame) {
    // A float is not finite when its exponent bits are all ones: one pass
    // without a branch, the search only when it finds one.
    std::uint32_t any = 0;
    for (std::size_t i = 0; i < count; ++i) {
        std::uint32_t bits;
        std::memcpy(&bits, samples + i, sizeof bits);
        any |= (~bits & 0x7f800000u) == 0;
    }
    if (!any) return;
    for (std::size_t i = 0; i < count; ++i) {
        if (std::isfinite(samples[i])) continue;
        const std::size_t frame = first_frame + i / static_cast<std::size_t>(channels);
        throw InputError(path.string(), 0, 0, "samples",
                         fmt::format("expected finite samples, got {} at frame {} ({:.6f} s), channel {}", samples[i],
                                     frame, static_cast<double>(frame) / rate_hz, i % channels + 1));
    }
}

void write_audio(const std::filesystem::path& path, const Audio& audio, SampleFormat format) {
    AVSI_ASSERT(audio.channels > 0 && audio.sample_rate_hz > 0);
    AVSI_ASSERT(audio.samples.size() % audio.channels == 0);
    // One writer for whole files and streams: the same format choice, clipping
    // and atomic commit (audio_stream.h).
    AudioFileWriter writer(path, audio.sample_rate_hz, audio.channels, format);
    writer.write(audio.samples.data(), audio.frames());
    writer.commit();
}

}  // namespace avsi
