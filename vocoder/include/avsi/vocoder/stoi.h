// Short-Time Objective Intelligibility: STOI (Taal, Hendriks, Heusdens &
// Jensen 2011, IEEE TASLP 19(7), eq. 1–6) and extended STOI (Jensen & Taal
// 2016, IEEE/ACM TASLP 24(11), §III), following the published reference
// implementation: resample to 10 kHz, remove frames more than 40 dB below
// the loudest clean frame (overlap-add reconstruction), 256-sample Hann
// frames with 50 % overlap and a 512-point FFT, 15 one-third-octave bands
// from 150 Hz, 30-frame (384 ms) segments, clipping at β = −15 dB (STOI).
#pragma once

#include <filesystem>
#include <span>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/vocoder/channels.h"

namespace avsi::vocoder {

struct StoiSettings {
    bool extended = false;  // ESTOI instead of STOI
};

// STOI (or ESTOI) of `degraded` against `clean`, both mono at
// `sample_rate_hz` and the same length. Resamples to 10 kHz when needed.
// Returns a value in about [0, 1] (STOI(x, x) = 1). Throws InputError when
// the lengths differ or fewer than 30 frames remain after silence removal.
double stoi(std::span<const double> clean, std::span<const double> degraded, double sample_rate_hz,
            const StoiSettings& settings = {});

// The same for two Audio buffers (mixed to mono; rates must agree).
double stoi(const Audio& clean, const Audio& degraded, const StoiSettings& settings = {});

// `avsi stoi`: reads the two files and scores them: one value (the channels
// mixed down to mono, with a note naming the file) or, with ChannelMode::Keep,
// one per channel (the clean file's channel c against the degraded file's).
// Mismatched rates, lengths or channel counts, and signals too short to
// score, throw InputError naming the degraded file and the clean one.
std::vector<double> stoi_files(const std::filesystem::path& clean, const std::filesystem::path& degraded,
                               const StoiSettings& settings = {}, ChannelMode channels = ChannelMode::Mono);

}  // namespace avsi::vocoder
