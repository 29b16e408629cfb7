// The cochlear-implant simulation path (steps 1–9 of ci_simulation.h): the
// reference vocoder's steps (reference_steps.h) with pulse carriers, shifted
// carrier bands with their own synthesis filters, n-of-m selection and
// current spread; one thread, the whole signal in memory.
#include "avsi/vocoder/ci_simulation.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <fmt/format.h>

#include "avsi/core/rng.h"
#include "avsi/vocoder/filters.h"
#include "reference_steps.h"

namespace avsi::vocoder {

namespace {

using detail::reference::Band;
using detail::reference::Signal;
namespace ref = detail::reference;

constexpr double kCiCochleaMm = 35.0;
// Spread contributions below −120 dB are left out.
constexpr double kSmallestWeight = 1e-6;

// Adds a unit rectangular pulse over [start, start + width) samples, each
// sample n holding its overlap with [n, n + 1).
void add_pulse(Signal& c, double start, double width) {
    const double end = start + width;
    for (auto n = static_cast<std::size_t>(std::max(0.0, std::floor(start)));
         n < c.size() && static_cast<double>(n) < end; ++n) {
        const double lo = std::max(start, static_cast<double>(n));
        const double hi = std::min(end, static_cast<double>(n) + 1.0);
        if (hi > lo) c[n] += hi - lo;
    }
}

// The analysis and the carrier bands (step 5).
struct CiBands {
    std::vector<Band> analysis;
    std::vector<Band> carrier;
};

CiBands design_ci_bands(const VocoderSettings& s, double rate) {
    const std::vector<double> edges = band_edges_hz(s);
    const std::vector<double> shifted = carrier_edges_hz(s);
    const int synthesis_order = s.synthesis_filter_order == 0 ? s.filter_order : s.synthesis_filter_order;
    CiBands bands;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
        BandInfo info;
        info.low_hz = edges[b];
        info.high_hz = edges[b + 1];
        info.centre_hz = std::sqrt(edges[b] * edges[b + 1]);
        info.carrier_low_hz = shifted[b];
        info.carrier_high_hz = shifted[b + 1];
        info.carrier_centre_hz = std::sqrt(shifted[b] * shifted[b + 1]);
        bands.analysis.push_back({butterworth_bandpass(s.filter_order, edges[b], edges[b + 1], rate), info});
        bands.carrier.push_back(
            {butterworth_bandpass(synthesis_order, shifted[b], shifted[b + 1], rate), info});
    }
    return bands;
}

// Step 4: carrier band b's carrier, through H'_b when pre-filtered.
Signal make_ci_carrier(const Band& band, std::size_t b, std::size_t frames, double rate, const VocoderSettings& s,
                       int channel) {
    Signal c;
    switch (s.carrier) {
        case CarrierType::Noise: c = ref::noise_carrier(s.seed, channel, b, frames); break;
        case CarrierType::Sine: c = ref::sine_carrier(band.info.carrier_centre_hz, rate, frames); break;
        case CarrierType::LowNoise:
            c = ref::low_noise_carrier(ref::noise_carrier(s.seed, channel, b, frames), band, s);
            break;
        case CarrierType::PulseTrain:
        case CarrierType::PoissonPulses: c = pulse_carrier(s, rate, b, channel, frames); break;
        case CarrierType::Pshc: break;  // refused by validate_settings
    }
    if (s.prefilter_carrier) c = ref::run_filter(band.band_pass, c, s.zero_phase);
    return c;
}

// H'(ê·c), or ê·c without the re-filter.
Signal synthesise(const Signal& envelope, const Signal& carrier, const Band& band, const VocoderSettings& s) {
    Signal y(envelope.size());
    for (std::size_t n = 0; n < y.size(); ++n) y[n] = envelope[n] * carrier[n];
    if (s.refilter_carrier) y = ref::run_filter(band.band_pass, y, s.zero_phase);
    return y;
}

double rms(const Signal& x) {
    return x.empty() ? 0.0 : std::sqrt(ref::sum_of_squares(x) / static_cast<double>(x.size()));
}

// What steps 1–6 leave for the rest: per band, the envelope, the carrier,
// the gain and the pre-gain output level; the analysis signals for n-of-m.
struct BandStages {
    std::vector<Signal> envelopes, carriers, analysis, outputs;
    std::vector<double> gains, own_rms;
};

BandStages envelopes_and_gains(const Signal& x, double rate, const VocoderSettings& s, const CiBands& bands,
                               int channel, ChannelResult& result) {
    const Sos lowpass = butterworth_lowpass(s.envelope_filter_order, s.envelope_cutoff_hz, rate);
    const bool keep_outputs = s.current_spread == CurrentSpread::None && s.n_of_m == 0;
    BandStages st;
    for (std::size_t b = 0; b < bands.analysis.size(); ++b) {
        Signal a = ref::run_filter(bands.analysis[b].band_pass, x, s.zero_phase);
        st.envelopes.push_back(ref::envelope_lowpass(ref::extract_envelope(a, s.envelope), lowpass, s));
        st.carriers.push_back(make_ci_carrier(bands.carrier[b], b, x.size(), rate, s, channel));
        Signal y = synthesise(st.envelopes[b], st.carriers[b], bands.carrier[b], s);
        BandInfo& info = result.bands[b];
        info.analysis_rms = rms(a);
        info.output_rms = rms(y);
        st.own_rms.push_back(info.output_rms);
        st.gains.push_back(ref::match_band_level(info, s));
        if (s.n_of_m > 0) st.analysis.push_back(std::move(a));
        if (keep_outputs) st.outputs.push_back(std::move(y));
    }
    return st;
}

// ρ_bk of step 8 for every pair with a weight (1 on the diagonal), from the
// envelopes before selection.
std::vector<std::vector<double>> spread_level_ratios(const BandStages& st, const CiBands& bands,
                                                     const std::vector<std::vector<double>>& w,
                                                     const VocoderSettings& s) {
    const std::size_t m = st.envelopes.size();
    std::vector<std::vector<double>> ratio(m, std::vector<double>(m, 0.0));
    for (std::size_t b = 0; b < m; ++b)
        for (std::size_t k = 0; k < m; ++k) {
            if (b == k) ratio[b][k] = 1.0;
            if (b == k || w[b][k] < kSmallestWeight) continue;
            const double level = rms(synthesise(st.envelopes[b], st.carriers[k], bands.carrier[k], s));
            ratio[b][k] = level > 0.0 ? st.own_rms[b] / level : 0.0;
        }
    return ratio;
}

// Step 7 applied: the envelope set to 0 in the frames its band was not kept.
void apply_selection(std::vector<Signal>& envelopes, const ChannelSelection& selection, double rate,
                     double frame_rate_hz) {
    for (std::size_t b = 0; b < envelopes.size(); ++b)
        for (std::size_t n = 0; n < envelopes[b].size(); ++n) {
            const auto f = static_cast<std::size_t>(static_cast<double>(n) * frame_rate_hz / rate);
            if (!((selection[std::min(f, selection.size() - 1)] >> b) & 1u)) envelopes[b][n] = 0.0;
        }
}

// Step 8: band k's output z_k from every channel's envelope.
Signal spread_band_output(const BandStages& st, const CiBands& bands, const std::vector<std::vector<double>>& w,
                          const std::vector<std::vector<double>>& ratio, std::size_t k, const VocoderSettings& s) {
    Signal mixed(st.carriers[k].size(), 0.0);
    for (std::size_t b = 0; b < st.envelopes.size(); ++b) {
        const double gain = w[b][k] * st.gains[b] * ratio[b][k];
        if (w[b][k] < kSmallestWeight || gain == 0.0) continue;
        for (std::size_t n = 0; n < mixed.size(); ++n) mixed[n] += gain * st.envelopes[b][n];
    }
    return synthesise(mixed, st.carriers[k], bands.carrier[k], s);
}

// Steps 8–9: every band's output (kept when asked) and their sum.
void sum_band_outputs(BandStages& st, const CiBands& bands, double rate, const VocoderSettings& s,
                      ChannelResult& result, bool keep_band_signals) {
    const std::size_t m = st.envelopes.size();
    std::vector<std::vector<double>> w, ratio;
    const bool mix = st.outputs.empty();
    if (mix) {
        std::vector<double> centres;
        for (const Band& band : bands.carrier) centres.push_back(band.info.carrier_centre_hz);
        w = spread_weights(s, centres);
        ratio = spread_level_ratios(st, bands, w, s);
        if (s.n_of_m > 0) apply_selection(st.envelopes, result.selection, rate, s.selection_frame_rate_hz);
    }
    for (std::size_t k = 0; k < m; ++k) {
        Signal z = mix ? spread_band_output(st, bands, w, ratio, k, s) : std::move(st.outputs[k]);
        if (!mix)
            for (double& v : z) v *= st.gains[k];
        result.bands[k].output_rms = rms(z);
        for (std::size_t n = 0; n < z.size(); ++n) result.samples[n] += z[n];
        if (keep_band_signals) result.band_signals.push_back(std::move(z));
    }
}

}  // namespace

std::vector<double> pulse_carrier(const VocoderSettings& s, double rate, std::size_t band, int channel,
                                  std::size_t frames) {
    Signal c(frames, 0.0);
    const double period = rate / s.pulse_rate_hz;  // in samples
    const double width = s.pulse_width_us * 1e-6 * rate;
    if (s.carrier == CarrierType::PoissonPulses) {
        Rng stream = Rng(s.seed).derive(fmt::format("channel{}/band{}/poisson", channel, band));
        for (double t = 0.0;;) {
            t += -std::log(1.0 - stream.uniform()) * period;  // exponential interval, mean 1/R
            if (!(t < static_cast<double>(frames))) break;
            add_pulse(c, t, width);
        }
        return c;
    }
    const double phase =
        s.pulse_phase == PulsePhase::Interleaved ? static_cast<double>(band) / static_cast<double>(s.bands) : 0.0;
    for (std::size_t k = 0;; ++k) {
        const double start = (static_cast<double>(k) + phase) * period;
        if (!(start < static_cast<double>(frames))) break;
        add_pulse(c, start, width);
    }
    return c;
}

std::vector<std::vector<double>> spread_weights(const VocoderSettings& s, const std::vector<double>& centres) {
    const std::size_t m = centres.size();
    std::vector<std::vector<double>> w(m, std::vector<double>(m, 0.0));
    for (std::size_t b = 0; b < m; ++b)
        for (std::size_t k = 0; k < m; ++k) {
            if (s.current_spread == CurrentSpread::None) {
                w[b][k] = b == k ? 1.0 : 0.0;
                continue;
            }
            const double distance = s.current_spread == CurrentSpread::DbPerMm
                                        ? kCiCochleaMm * std::abs(greenwood_position(centres[k]) -
                                                                      greenwood_position(centres[b]))
                                        : std::abs(std::log2(centres[k] / centres[b]));
            w[b][k] = std::pow(10.0, -s.spread_slope_db * distance / 20.0);
        }
    return w;
}

ChannelSelection select_channels(const std::vector<std::vector<double>>& analysis, int n, double rate,
                                 double frame_rate_hz) {
    const std::size_t m = analysis.size();
    const std::size_t samples = m ? analysis[0].size() : 0;
    if (samples == 0) return {};
    const auto frames = static_cast<std::size_t>(static_cast<double>(samples - 1) * frame_rate_hz / rate) + 1;
    std::vector<std::vector<double>> energy(frames, std::vector<double>(m, 0.0));
    for (std::size_t b = 0; b < m; ++b)
        for (std::size_t i = 0; i < samples; ++i) {
            const auto f = std::min(frames - 1, static_cast<std::size_t>(static_cast<double>(i) * frame_rate_hz / rate));
            energy[f][b] += analysis[b][i] * analysis[b][i];
        }
    ChannelSelection selection(frames, 0);
    std::vector<std::size_t> order(m);
    for (std::size_t f = 0; f < frames; ++f) {
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::stable_sort(order.begin(), order.end(),
                         [&e = energy[f]](std::size_t a, std::size_t b) { return e[a] > e[b]; });
        for (int i = 0; i < std::min<int>(n, static_cast<int>(m)); ++i) selection[f] |= std::uint64_t{1} << order[i];
    }
    return selection;
}

namespace detail {

ChannelResult vocode_channel_ci(std::span<const double> samples, double rate, const VocoderSettings& s, int channel,
                                bool keep_band_signals) {
    validate_settings(s, rate);
    const Signal x(samples.begin(), samples.end());
    const CiBands bands = design_ci_bands(s, rate);
    ChannelResult result;
    for (const Band& band : bands.analysis) result.bands.push_back(band.info);
    result.samples.assign(x.size(), 0.0);
    if (x.empty()) return result;
    BandStages st = envelopes_and_gains(x, rate, s, bands, channel, result);
    if (s.n_of_m > 0) {
        result.selection = select_channels(st.analysis, s.n_of_m, rate, s.selection_frame_rate_hz);
        st.analysis.clear();
    }
    sum_band_outputs(st, bands, rate, s, result, keep_band_signals);
    ref::match_output_level(result, x, s);
    return result;
}

}  // namespace detail

}  // namespace avsi::vocoder
