// Masking noise for speech-in-noise tests: speech-shaped noise with the
// long-term average spectrum (LTAS) of a set of recordings (Welch's method:
// Hann frames, 50 % overlap, averaged power spectra), or a given noise
// recording, mixed with speech at a given signal-to-noise ratio.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/audio_stream.h"

namespace avsi::vocoder {

// Average power per FFT bin (0 … fft_size/2) at a sample rate.
struct LongTermSpectrum {
    double sample_rate_hz = 0.0;
    std::size_t fft_size = 0;
    std::vector<double> power;

    // Power at `frequency_hz`, linearly interpolated; 0 above Nyquist.
    double at(double frequency_hz) const;
};

// The LTAS over every recording (channels mixed to mono). Recordings at
// another rate than the first are resampled to it. Throws InputError when
// the set is empty or holds no full frame.
LongTermSpectrum long_term_spectrum(const std::vector<Audio>& recordings, std::size_t fft_size = 2048);

// `frames` samples of seeded Gaussian noise at `sample_rate_hz` whose power
// spectrum follows `spectrum` (shaped in the frequency domain), RMS 1.
std::vector<double> speech_shaped_noise(const LongTermSpectrum& spectrum, std::size_t frames,
                                        double sample_rate_hz, std::uint64_t seed);

// What the speech level in the SNR is measured over.
enum class SnrReference {
    WholeSignal,   // RMS over every sample, pauses included
    ActiveFrames   // RMS over 20 ms frames within 40 dB of the loudest frame (pauses excluded)
};

struct MixSettings {
    double snr_db = 0.0;
    SnrReference reference = SnrReference::WholeSignal;
    std::uint64_t seed = 1;  // picks the excerpt of a noise recording longer than the speech
};

struct MixResult {
    Audio audio;
    double speech_rms = 0.0;      // over the reference (whole signal or active frames)
    double noise_rms = 0.0;       // of the scaled noise, whole signal
    double limit_gain_db = 0.0;   // < 0 when the mixture was scaled down to keep |x| ≤ 1
};

// The speech RMS as `reference` defines it.
double speech_level_rms(std::span<const double> speech, double sample_rate_hz, SnrReference reference);

// The same over a source's channels mixed to mono (as Audio::mono), read in
// blocks: one pass for the whole signal, two for active frames (the
// loudest frame first). Memory bounded by the block, whatever the length.
double speech_level_rms(AudioSource& speech, SnrReference reference);

// Mono noise samples by position, for mixing block by block: a noise
// recording read from its file (channels mixed as Audio::mono does), or
// samples in memory.
class NoiseSamples {
public:
    virtual ~NoiseSamples() = default;
    virtual std::size_t frames() const = 0;
    // Samples [from, from + count) into `out` (from + count ≤ frames()).
    virtual void read(std::size_t from, std::size_t count, double* out) = 0;
};

// Noise samples in memory (the span must outlive it).
class NoiseInMemory : public NoiseSamples {
public:
    explicit NoiseInMemory(std::span<const double> noise) : m_noise(noise) {}
    std::size_t frames() const override { return m_noise.size(); }
    void read(std::size_t from, std::size_t count, double* out) override;

private:
    std::span<const double> m_noise;
};

// A noise recording read from its file as needed; the file's rate must be
// the speech's (load_noise resamples otherwise, in memory).
class NoiseFile : public NoiseSamples {
public:
    explicit NoiseFile(const std::filesystem::path& path);
    int sample_rate_hz() const { return m_reader.sample_rate_hz(); }
    std::size_t frames() const override { return m_reader.frames(); }
    void read(std::size_t from, std::size_t count, double* out) override;

private:
    AudioFileReader m_reader;
    std::size_t m_position = 0;
    std::vector<float> m_block;
};

// What mix_stream measured: MixResult without the audio.
struct MixReport {
    double speech_rms = 0.0;
    double noise_rms = 0.0;
    double limit_gain_db = 0.0;
};

// mix_at_snr from a source to a sink in blocks, the same samples: passes
// over the speech for its level, over the noise excerpt for its level, over
// both for the mixture's peak, and one that writes. Memory bounded by the
// block, whatever the lengths.
MixReport mix_stream(AudioSource& speech, NoiseSamples& noise, const MixSettings& settings, AudioSink& output);

// The mixture as a source (for vocoding it on the fly): mix_stream's
// samples, computed block by block from any position. Construction makes
// the measuring passes; `speech` and `noise` must outlive it.
class MixedSource : public AudioSource {
public:
    MixedSource(AudioSource& speech, NoiseSamples& noise, const MixSettings& settings);
    int sample_rate_hz() const override { return m_speech.sample_rate_hz(); }
    int channels() const override { return m_speech.channels(); }
    std::size_t frames() const override { return m_speech.frames(); }
    std::size_t read(float* out, std::size_t frames) override;
    void seek(std::size_t frame) override;
    const MixReport& report() const { return m_report; }

private:
    AudioSource& m_speech;
    NoiseSamples& m_noise;
    MixReport m_report;
    double m_gain = 0.0;
    double m_scale = 1.0;
    std::size_t m_offset = 0;  // of the excerpt in a longer noise
    bool m_loop = false;       // or the noise looped
    std::size_t m_position = 0;
    std::vector<float> m_speech_block;
    std::vector<double> m_noise_block;
};

// Adds `noise` (mono, at the speech's rate) to every channel of `speech` so
// that 20·log10(speech_rms / noise_rms) = snr_db. A noise longer than the
// speech contributes a seeded excerpt; a shorter one is looped (logged).
// If the mixture would clip it is scaled down as a whole (logged, reported).
MixResult mix_at_snr(const Audio& speech, std::span<const double> noise, const MixSettings& settings);

// A noise recording as mono samples at `sample_rate_hz` (resampled if needed).
std::vector<double> load_noise(const std::filesystem::path& path, double sample_rate_hz);

std::string to_string(SnrReference reference);
SnrReference parse_snr_reference(const std::string& text, const std::string& field = "snr-reference");

}  // namespace avsi::vocoder
