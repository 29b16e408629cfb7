// The channel vocoder as a cochlear-implant (CI) simulation: the stages
// labs add to Shannon et al.'s (1995) vocoder when they simulate CI hearing,
// run by every entry point of vocoder.h when uses_ci_simulation(settings).
// One thread, the whole signal in memory (vocoder/src/ci_simulation.cpp).
// For each band b (analysis filter H_b, carrier band filter H'_b):
//   1–3. envelope ê_b = max(L(env(H_b(x))), 0)      as reference.h
//   4.   carrier c_b on carrier band b:
//          pulse train: unit rectangular pulses of width W at onsets
//            t = (k + φ_b)/R, φ_b = b/bands interleaved, 0 simultaneous;
//          Poisson: the same pulses at the times of a Poisson process of
//            rate R (exponential intervals, stream "channel<c>/band<b>/poisson");
//          noise, sine (at carrier band b's geometric centre), low-noise;
//        each sample n holds the pulse's overlap with [n, n + 1), so onsets
//        and widths are exact at any sample rate
//   5.   carrier bands: the analysis edges moved shift mm basally along
//        Greenwood's (1990) map, x' = x + shift / 35 mm; H'_b is a
//        Butterworth band-pass of synthesis_filter_order (the analysis order
//        unless set) on them
//   6.   band gains g_b = rms(H_b(x)) / rms(H'_b(ê_b·c_b)) (before selection)
//   7.   n-of-m: in each frame f = ⌊n·F / rate⌋, the n bands of largest
//        Σ_{n∈f} H_b(x)[n]² keep ê_b, the others' ê_b = 0 (ties: lower band)
//   8.   current spread (SPIRAL, Grange et al. 2017): band k's output
//          z_k = H'_k(c_k · Σ_b w_bk·g_b·ρ_bk·ê_b),
//          w_bk = 10^(−S·d(b, k)/20), d in octaves (|log2(f'_k/f'_b)|) or
//          in mm (35·|x(f'_k) − x(f'_b)|) between carrier centres f';
//          ρ_bk = rms(H'_b(ê_b·c_b)) / rms(H'_k(ê_b·c_k)), so that channel b
//          reaches band k exactly w_bk below its own level-matched level;
//          without spread w = identity: z_b = g_b·H'_b(ê_b·c_b)
//   9.   sum Σ_k z_k, overall level and anti-clipping scale as reference.h.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "avsi/vocoder/vocoder.h"

namespace avsi::vocoder {

// Band b's pulse carrier (pulse-train or Poisson, step 4) over `frames`
// samples at `rate`, for channel `channel`'s streams; settings validated.
std::vector<double> pulse_carrier(const VocoderSettings& settings, double rate, std::size_t band, int channel,
                                  std::size_t frames);

// The spread weights w[b][k] of step 8 (linear amplitude; the identity
// without current spread), from the carrier band centres.
std::vector<std::vector<double>> spread_weights(const VocoderSettings& settings,
                                                const std::vector<double>& carrier_centres_hz);

// Step 7: the n bands of largest energy in each frame of `analysis` (one
// signal per band, at most 64 bands), frame f = ⌊n·frame_rate_hz / rate⌋.
ChannelSelection select_channels(const std::vector<std::vector<double>>& analysis, int n, double rate,
                                 double frame_rate_hz);

namespace detail {
// vocode_channel for settings with uses_ci_simulation (steps 1–9).
ChannelResult vocode_channel_ci(std::span<const double> samples, double rate, const VocoderSettings& settings,
                                int channel, bool keep_band_signals);
}  // namespace detail

}  // namespace avsi::vocoder
