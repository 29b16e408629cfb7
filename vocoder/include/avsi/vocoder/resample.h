// Sample-rate conversion through libsoxr (the SoX resampler, "very high
// quality" recipe: linear phase, passband to 95 % of the lower Nyquist,
// 175 dB stop-band rejection).
#pragma once

#include <span>
#include <vector>

namespace avsi::vocoder {

// `signal` at `from_hz`, converted to `to_hz`. Output length is
// round(n · to/from), aligned in time with the input (the filter's group
// delay is removed). Returns a copy when the rates are equal.
std::vector<double> resample(std::span<const double> signal, double from_hz, double to_hz);

}  // namespace avsi::vocoder
