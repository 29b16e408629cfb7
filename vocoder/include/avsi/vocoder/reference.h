// The channel vocoder written as its equations (Shannon et al. 1995; the
// options of Cychosz, Winn & Goupell 2024), one band at a time, on one
// thread, over the whole signal in memory: the path to read next to the
// papers, and the one the fast path (vocode, vocode_stream, vocode_channel
// in vocoder.h) is held to. Both give the same output bit for bit
// (tests/vocoder/reference_test.cpp); vocoder/src/reference.cpp lists the
// steps and the three choices that fix the rounding.
//
// This path is slower and its memory grows with the signal's length: use
// vocode() for work, this to check it.
//
// Usage:
//   const auto fast = avsi::vocoder::vocode(audio, settings);
//   const auto plain = avsi::vocoder::vocode_reference(audio, settings);  // the same samples
#pragma once

#include <span>

#include "avsi/core/audio.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::vocoder {

// vocode() by the equations: the same result (samples, bands, gains,
// peak and limit), the same errors and the same debug message.
VocoderResult vocode_reference(const Audio& input, const VocoderSettings& settings);

// vocode_channel() by the equations: the same result.
ChannelResult vocode_channel_reference(std::span<const double> samples, double sample_rate_hz,
                                       const VocoderSettings& settings, int channel = 0,
                                       bool keep_band_signals = false);

}  // namespace avsi::vocoder
