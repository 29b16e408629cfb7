// The channel vocoder of Shannon, Zeng, Kamath, Wygonski & Ekelid (1995),
// with the options reviewed by Cychosz, Winn & Goupell (2024), as its
// equations: one band at a time, over the whole signal, on one thread.
// For each band b, with H_b its Butterworth band-pass (filters.h) and L the
// envelope's Butterworth low-pass:
//   1. analysis filter     a_b = H_b(x)
//   2. envelope            e_b = max(a_b, 0), |a_b|, or |a_b + j·Hilbert{a_b}|
//   3. envelope low-pass   ê_b = max(L(e_b), 0)
//   4. carrier             c_b = noise, sin(2π·f_b·t) at the band's geometric
//                          centre f_b, or low-noise noise; H_b(c_b) when
//                          the carrier is pre-filtered
//   5. synthesis filter    y_b = H_b(ê_b·c_b)  (ê_b·c_b when not re-filtered)
//   6. sum                 s = Σ_b g_b·y_b, g_b = rms(a_b) / rms(y_b)
//   7. level               out = g·s, g = rms(x) / rms(s)
// and, over all channels, out·0.999/peak when the peak exceeds full scale.
// With zero phase every filter runs forward, then backward.
//
// Three choices fix the rounding, and so the exact output, which the fast
// path (vocode, vocode_stream, vocode_channel) reproduces bit for bit:
//   - every filter runs through SosBank's kernels (filters.h), which factor
//     the Butterworth numerators out of the sections;
//   - each y_b is rounded to single precision before the sum (the fast path
//     keeps band outputs as 4-byte floats between its passes);
//   - every sum runs in sample order (bands in band order) from 0, and the
//     noise and sine carriers are made as described at their functions.
#include "avsi/vocoder/reference.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <numbers>

#include <fmt/format.h>

#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/hilbert.h"
#include "avsi/vocoder/ci_simulation.h"
#include "reference_steps.h"

namespace avsi::vocoder {

namespace detail::reference {

std::vector<Band> design_bands(const VocoderSettings& s, double rate) {
    const std::vector<double> edges = band_edges_hz(s);
    std::vector<Band> bands;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
        Band band;
        band.band_pass = butterworth_bandpass(s.filter_order, edges[b], edges[b + 1], rate);
        band.info.low_hz = edges[b];
        band.info.high_hz = edges[b + 1];
        band.info.centre_hz = std::sqrt(edges[b] * edges[b + 1]);
        bands.push_back(band);
    }
    return bands;
}

// y = H(x) from rest over the whole signal, then backward in time for zero
// phase; through a one-lane SosBank, so that every value rounds as in the
// fast path's banks.
Signal run_filter(const Sos& cascade, const Signal& x, bool zero_phase) {
    const SosBank bank({cascade});
    const std::size_t stride = bank.stride();
    std::vector<double> rows(x.size() * stride, 0.0);
    for (std::size_t n = 0; n < x.size(); ++n) rows[n * stride] = x[n];
    bank.process(rows.data(), x.size(), false);
    if (zero_phase) bank.process(rows.data(), x.size(), true);
    Signal y(x.size());
    for (std::size_t n = 0; n < x.size(); ++n) y[n] = rows[n * stride];
    return y;
}

// Σ x[n]² in sample order.
double sum_of_squares(const Signal& x) {
    double sum = 0.0;
    for (double v : x) sum += v * v;
    return sum;
}

double gain_db(double gain) { return 20.0 * std::log10(gain); }

// ------------------------------------------------------------- steps 1–3

// 1. The band's part of the input: a = H_b(x).
Signal analysis_filter(const Signal& x, const Band& band, const VocoderSettings& s) {
    return run_filter(band.band_pass, x, s.zero_phase);
}

// 2. The band's temporal envelope: max(a, 0) (half-wave), |a| (full-wave),
// or the magnitude of the analytic signal a + j·Hilbert{a}.
Signal extract_envelope(const Signal& a, EnvelopeMethod method) {
    Signal e(a.size());
    switch (method) {
        case EnvelopeMethod::HalfWaveRectify:
            for (std::size_t n = 0; n < a.size(); ++n) e[n] = std::max(a[n], 0.0);
            break;
        case EnvelopeMethod::FullWaveRectify:
            for (std::size_t n = 0; n < a.size(); ++n) e[n] = std::abs(a[n]);
            break;
        case EnvelopeMethod::Hilbert: e = hilbert_envelope(a); break;
    }
    return e;
}

// 3. The envelope low-pass, negative values set to 0: ê = max(L(e), 0).
Signal envelope_lowpass(const Signal& e, const Sos& lowpass, const VocoderSettings& s) {
    Signal smoothed = run_filter(lowpass, e, s.zero_phase);
    for (double& v : smoothed) v = std::max(v, 0.0);
    return smoothed;
}

// ------------------------------------------------------------- step 4

// White noise in [-1, 1): the stream Rng(seed).derive("channel<c>/band<b>"),
// each 64-bit draw giving two samples of 32-bit resolution, its low half
// first: c[t] = bits·2^-31 − 1.
Signal noise_carrier(std::uint64_t seed, int channel, std::size_t band, std::size_t frames) {
    Rng stream = Rng(seed).derive(fmt::format("channel{}/band{}", channel, band));
    Signal c(frames);
    std::uint64_t draw = 0;
    for (std::size_t t = 0; t < frames; ++t) {
        if (t % 2 == 0) draw = stream.next_u64();
        const auto bits = static_cast<std::uint32_t>(t % 2 == 0 ? draw : draw >> 32);
        c[t] = static_cast<double>(bits) * 0x1p-31 - 1.0;
    }
    return c;
}

// sin(ω·t), ω = 2π·f / rate, zero phase: the imaginary part of a phasor
// p[t + 1] = p[t]·e^{jω}, set to e^{jωt} exactly every 1024 samples (a
// multiply per sample instead of a sine, its rounding error bounded).
Signal sine_carrier(double centre_hz, double rate, std::size_t frames) {
    const double w = 2.0 * std::numbers::pi * centre_hz / rate;
    const std::complex<double> step = std::polar(1.0, w);
    std::complex<double> phasor;
    Signal c(frames);
    for (std::size_t t = 0; t < frames; ++t) {
        if (t % 1024 == 0) phasor = std::polar(1.0, w * static_cast<double>(t));
        c[t] = phasor.imag();
        phasor *= step;
    }
    return c;
}

// Low-noise noise (Pumplin 1985; Kohlrausch, Fassel, van der Heijden et al.
// 1997): noise band-limited by H_b, then `iterations` times divided by its
// own Hilbert envelope (floored at 10^-9 of the envelope's mean) and
// band-limited again; each round flattens the envelope further.
Signal low_noise_carrier(const Signal& noise, const Band& band, const VocoderSettings& s) {
    Signal c = run_filter(band.band_pass, noise, s.zero_phase);
    for (int it = 0; it < s.low_noise_iterations; ++it) {
        const Signal envelope = hilbert_envelope(c);
        double mean = 0.0;
        for (double e : envelope) mean += e;
        mean /= static_cast<double>(std::max<std::size_t>(c.size(), 1));
        const double floor = 1e-9 * std::max(mean, 1e-300);
        for (std::size_t n = 0; n < c.size(); ++n) c[n] /= std::max(envelope[n], floor);
        c = run_filter(band.band_pass, c, s.zero_phase);
    }
    return c;
}

// 4. Band b's carrier, through H_b when pre-filtered.
Signal make_carrier(const Band& band, std::size_t b, std::size_t frames, double rate, const VocoderSettings& s,
                    int channel) {
    Signal c;
    switch (s.carrier) {
        case CarrierType::Noise: c = noise_carrier(s.seed, channel, b, frames); break;
        case CarrierType::Sine: c = sine_carrier(band.info.centre_hz, rate, frames); break;
        case CarrierType::LowNoise: c = low_noise_carrier(noise_carrier(s.seed, channel, b, frames), band, s); break;
        case CarrierType::PulseTrain:
        case CarrierType::PoissonPulses:
        case CarrierType::Pshc:  // uses_ci_simulation: these run on the CI path (ci_simulation.cpp)
            AVSI_ASSERT(false);
            break;
    }
    if (s.prefilter_carrier) c = run_filter(band.band_pass, c, s.zero_phase);
    return c;
}

// ------------------------------------------------------------- steps 5–7

// 5. Modulation, then the synthesis filter: y = H_b(ê·c), or ê·c without
// the re-filter.
Signal synthesis_filter(const Signal& envelope, const Signal& carrier, const Band& band, const VocoderSettings& s) {
    Signal y(envelope.size());
    for (std::size_t n = 0; n < y.size(); ++n) y[n] = envelope[n] * carrier[n];
    if (s.refilter_carrier) y = run_filter(band.band_pass, y, s.zero_phase);
    return y;
}

// Steps 1–5 of band b: its output y_b, and the levels of a_b and y_b in
// `info` (output_rms before the band gain).
Signal vocode_band(const Signal& x, double rate, const VocoderSettings& s, const Band& band, std::size_t b,
                   const Sos& lowpass, int channel, BandInfo& info) {
    const Signal a = analysis_filter(x, band, s);
    const Signal envelope = envelope_lowpass(extract_envelope(a, s.envelope), lowpass, s);
    const Signal y = synthesis_filter(envelope, make_carrier(band, b, x.size(), rate, s, channel), band, s);
    const double frames = static_cast<double>(x.size());
    info.analysis_rms = std::sqrt(sum_of_squares(a) / frames);
    info.output_rms = std::sqrt(sum_of_squares(y) / frames);
    return y;
}

// The band gain g_b = rms(a_b) / rms(y_b) (1 without band level matching or
// for a silent band), and the band's output level after it.
double match_band_level(BandInfo& info, const VocoderSettings& s) {
    const double rms = info.output_rms;
    const double gain = s.match_band_rms && rms > 0.0 ? info.analysis_rms / rms : 1.0;
    info.output_rms = rms * gain;
    return gain;
}

// 6. s[n] = Σ_b g_b·float(y_b[n]), in band order from 0.
Signal sum_bands(const std::vector<Signal>& outputs, const std::vector<double>& gains, std::size_t frames) {
    Signal sum(frames);
    for (std::size_t n = 0; n < frames; ++n) {
        double s = 0.0;
        for (std::size_t b = 0; b < outputs.size(); ++b) s += gains[b] * static_cast<float>(outputs[b][n]);
        sum[n] = s;
    }
    return sum;
}

// Band b's part of the sum: g_b·float(y_b[n]).
Signal band_signal(const Signal& output, double gain) {
    Signal signal(output.size());
    for (std::size_t n = 0; n < output.size(); ++n) signal[n] = gain * static_cast<float>(output[n]);
    return signal;
}

// 7. out = g·s with g = sqrt(Σx² / Σs²), the input's RMS over the sum's,
// unless overall level matching is off or the sum is silent.
void match_output_level(ChannelResult& result, const Signal& x, const VocoderSettings& s) {
    const double in_sq = sum_of_squares(x);
    const double out_sq = sum_of_squares(result.samples);
    if (!s.match_output_rms || !(out_sq > 0.0)) return;
    const double gain = std::sqrt(in_sq / out_sq);
    for (double& v : result.samples) v *= gain;
    result.output_gain_db = in_sq > 0.0 ? gain_db(gain) : -INFINITY;
}

}  // namespace detail::reference

namespace {

using namespace detail::reference;

// The anti-clipping scale of the whole output: 0.999 / peak when the peak
// exceeds 1, else 1; reported in `result` and logged.
double limit_scale(const std::vector<ChannelResult>& channels, VocoderResult& result) {
    double peak = 0.0;
    for (const ChannelResult& channel : channels)
        for (double v : channel.samples) peak = std::max(peak, std::abs(v));
    result.peak_before_limit = peak;
    if (!(peak > 1.0)) return 1.0;
    const double scale = 0.999 / peak;
    result.limit_gain_db = gain_db(scale);
    log_debug("vocoder: output peak {:.3f} exceeds full scale; scaled the whole output by {:.2f} dB "
                "to avoid clipping",
                peak, result.limit_gain_db);
    return scale;
}

}  // namespace

ChannelResult vocode_channel_reference(std::span<const double> samples, double rate, const VocoderSettings& s,
                                       int channel, bool keep_band_signals) {
    using namespace detail::reference;
    if (uses_ci_simulation(s)) return detail::vocode_channel_ci(samples, rate, s, channel, keep_band_signals);
    validate_settings(s, rate);
    const Signal x(samples.begin(), samples.end());
    const std::vector<Band> bands = design_bands(s, rate);
    ChannelResult result;
    for (const Band& band : bands) result.bands.push_back(band.info);
    result.samples.assign(x.size(), 0.0);
    if (x.empty()) return result;
    const Sos lowpass = butterworth_lowpass(s.envelope_filter_order, s.envelope_cutoff_hz, rate);
    std::vector<Signal> outputs;
    std::vector<double> gains;
    for (std::size_t b = 0; b < bands.size(); ++b) {
        outputs.push_back(vocode_band(x, rate, s, bands[b], b, lowpass, channel, result.bands[b]));
        gains.push_back(match_band_level(result.bands[b], s));
    }
    result.samples = sum_bands(outputs, gains, x.size());
    if (keep_band_signals)
        for (std::size_t b = 0; b < bands.size(); ++b) result.band_signals.push_back(band_signal(outputs[b], gains[b]));
    match_output_level(result, x, s);
    return result;
}

VocoderResult vocode_reference(const Audio& input, const VocoderSettings& s) {
    if (input.channels < 1 || input.sample_rate_hz <= 0)
        throw InputError(Diagnostic{"", 0, 0, "audio",
                                    fmt::format("expected at least one channel and a positive sample "
                                                "rate, got {} channels at {} Hz",
                                                input.channels, input.sample_rate_hz)});
    validate_settings(s, input.sample_rate_hz);
    VocoderResult result;
    result.audio.sample_rate_hz = input.sample_rate_hz;
    result.audio.channels = input.channels;
    // Every channel gets channel 0's noise carrier: a dual-mono input stays
    // dual-mono (independent carriers would make it dichotic).
    std::vector<ChannelResult> channels;
    for (int c = 0; c < input.channels; ++c) {
        const std::vector<float> samples = input.channel(c);
        const Signal x(samples.begin(), samples.end());
        channels.push_back(vocode_channel_reference(x, input.sample_rate_hz, s, 0));
    }
    result.bands = channels[0].bands;
    result.output_gain_db = channels[0].output_gain_db;
    result.selection = channels[0].selection;
    const double scale = limit_scale(channels, result);
    const std::size_t frames = input.frames();
    const std::size_t nc = static_cast<std::size_t>(input.channels);
    result.audio.samples.resize(frames * nc);
    for (std::size_t n = 0; n < frames; ++n)
        for (std::size_t c = 0; c < nc; ++c)
            result.audio.samples[n * nc + c] = static_cast<float>(channels[c].samples[n] * scale);
    return result;
}

}  // namespace avsi::vocoder
