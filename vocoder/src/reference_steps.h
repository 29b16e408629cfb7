// The steps of the one-thread reference vocoder (reference.cpp) that the
// cochlear-implant simulation path (ci_simulation.cpp) runs as well: the
// filters run from rest through SosBank's kernels, the envelope, the noise,
// sine and low-noise carriers, and the overall level. Their contracts and
// equations are at their definitions in reference.cpp.
#pragma once

#include <cstdint>
#include <vector>

#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::vocoder::detail::reference {

using Signal = std::vector<double>;

// One band: its band-pass filter and what is reported about it.
struct Band {
    Sos band_pass;
    BandInfo info;
};

// y = H(x) from rest over the whole signal (then backward for zero phase).
Signal run_filter(const Sos& cascade, const Signal& x, bool zero_phase);
// Σ x[n]² in sample order.
double sum_of_squares(const Signal& x);
// Step 2: max(a, 0), |a| or the analytic signal's magnitude.
Signal extract_envelope(const Signal& a, EnvelopeMethod method);
// Step 3: ê = max(L(e), 0).
Signal envelope_lowpass(const Signal& e, const Sos& lowpass, const VocoderSettings& s);
// Step 4's carriers: the seeded noise stream "channel<c>/band<b>", a zero-phase
// sine, low-noise noise band-limited by `band`.
Signal noise_carrier(std::uint64_t seed, int channel, std::size_t band, std::size_t frames);
Signal sine_carrier(double centre_hz, double rate, std::size_t frames);
Signal low_noise_carrier(const Signal& noise, const Band& band, const VocoderSettings& s);
// The band gain g_b = rms(a_b) / rms(y_b) (1 without band level matching or
// for a silent band); info.output_rms becomes the level after it.
double match_band_level(BandInfo& info, const VocoderSettings& s);
// Step 7: the summed output's RMS set to the input's (when asked).
void match_output_level(ChannelResult& result, const Signal& x, const VocoderSettings& s);

}  // namespace avsi::vocoder::detail::reference
