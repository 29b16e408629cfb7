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
