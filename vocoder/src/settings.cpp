// VocoderSettings: the names of its choices and their parsers, validation,
// the band edges (Greenwood's 1990 frequency–place function,
// F = 165.4·(10^(2.1x) − 0.88), or equal ratios, or equal widths) and the
// methods-section text of describe() (the checklist of Cychosz, Winn &
// Goupell 2024, "How to vocode", JASA 155). No signal processing here.
#include "avsi/vocoder/vocoder.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <initializer_list>
#include <numbers>
#include <string_view>

#include <fmt/format.h>

#include "avsi/vocoder/filters.h"

namespace avsi::vocoder {

namespace {

std::string format_hz(double hz) { return fmt::format("{:.1f}", hz); }

std::string join_hz(const std::vector<double>& values) {
    std::string out;
    for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + format_hz(values[i]);
    return out;
}

std::string ordinal(int n) {
    const char* suffix = "th";
    if (n % 100 < 11 || n % 100 > 13) {
        if (n % 10 == 1) suffix = "st";
        if (n % 10 == 2) suffix = "nd";
        if (n % 10 == 3) suffix = "rd";
    }
    return fmt::format("{}{}", n, suffix);
}

template <typename Enum>
Enum parse_enum(const std::string& text, const std::string& field, std::initializer_list<Enum> values) {
    std::vector<std::string> names;
    for (Enum v : values) {
        if (to_string(v) == text) return v;
        names.push_back(to_string(v));
    }
    std::string message = fmt::format("expected one of {}, got \"{}\"", fmt::join(names, ", "), text);
    const std::string hint = closest_match(text, names);
    if (!hint.empty()) message += fmt::format(" (did you mean \"{}\"?)", hint);
    throw InputError(Diagnostic{"", 0, 0, field, message});
}

}  // namespace

// ------------------------------------------------------------- names

std::string to_string(BandSpacing spacing) {
    switch (spacing) {
        case BandSpacing::Greenwood: return "greenwood";
        case BandSpacing::Log: return "log";
        case BandSpacing::Linear: return "linear";
        case BandSpacing::Explicit: return "explicit";
    }
    return "?";
}

std::string to_string(EnvelopeMethod method) {
    switch (method) {
        case EnvelopeMethod::HalfWaveRectify: return "rectify";
        case EnvelopeMethod::FullWaveRectify: return "full-wave";
        case EnvelopeMethod::Hilbert: return "hilbert";
    }
    return "?";
}

std::string to_string(CarrierType carrier) {
    switch (carrier) {
        case CarrierType::Noise: return "noise";
        case CarrierType::Sine: return "sine";
        case CarrierType::LowNoise: return "low-noise";
    }
    return "?";
}

BandSpacing parse_band_spacing(const std::string& text, const std::string& field) {
    return parse_enum(text, field,
                      {BandSpacing::Greenwood, BandSpacing::Log, BandSpacing::Linear, BandSpacing::Explicit});
}

EnvelopeMethod parse_envelope_method(const std::string& text, const std::string& field) {
    return parse_enum(text, field,
                      {EnvelopeMethod::HalfWaveRectify, EnvelopeMethod::FullWaveRectify, EnvelopeMethod::Hilbert});
}

CarrierType parse_carrier_type(const std::string& text, const std::string& field) {
    return parse_enum(text, field, {CarrierType::Noise, CarrierType::Sine, CarrierType::LowNoise});
}

// ------------------------------------------------------------- validation

namespace {

// Adds a problem with one field of the settings.
using AddProblem = std::function<void(const std::string& field, std::string message)>;

// The explicit band edges: bands + 1 increasing frequencies from low_hz to
// high_hz, and none unless the spacing is explicit.
void check_edges(const VocoderSettings& s, const AddProblem& add) {
    if (s.spacing != BandSpacing::Explicit) {
        if (!s.edges_hz.empty())
            add("edges_hz", fmt::format("expected no explicit edges with {} spacing (set spacing to "
                                        "explicit to use them), got {} edges",
                                        to_string(s.spacing), s.edges_hz.size()));
        return;
    }
    const auto& e = s.edges_hz;
    if (e.size() != static_cast<std::size_t>(std::max(s.bands, 0)) + 1)
        add("edges_hz", fmt::format("expected bands + 1 = {} edges, got {}", s.bands + 1, e.size()));
    for (std::size_t i = 0; i < e.size(); ++i) {
        if (!std::isfinite(e[i]) || e[i] <= 0.0)
            add(fmt::format("edges_hz[{}]", i), fmt::format("expected a frequency above 0 Hz, got {}", e[i]));
        else if (i > 0 && !(e[i] > e[i - 1]))
            add(fmt::format("edges_hz[{}]", i),
                fmt::format("expected increasing edges, above {} Hz, got {}", e[i - 1], e[i]));
    }
    if (!e.empty() && (e.front() != s.low_hz || e.back() != s.high_hz))
        add("edges_hz", fmt::format("expected the first and last edge to equal low_hz and high_hz "
                                    "({} and {} Hz), got {} and {} Hz",
                                    s.low_hz, s.high_hz, e.front(), e.back()));
}

}  // namespace

void validate_settings(const VocoderSettings& s, double rate, const std::string& source) {
    DiagnosticList problems;
    const AddProblem add = [&](const std::string& field, std::string message) {
        problems.add(source, 0, 0, "vocoder." + field, std::move(message));
    };
    const double nyquist = rate / 2.0;
    const std::string rate_note = fmt::format("the Nyquist frequency ({} Hz) of the {} Hz input",
                                              format_hz(nyquist), format_hz(rate));
    if (s.bands < 1 || s.bands > 64) add("bands", fmt::format("expected an integer in [1, 64], got {}", s.bands));
    if (!std::isfinite(s.low_hz) || s.low_hz <= 0.0)
        add("low_hz", fmt::format("expected a frequency above 0 Hz, got {}", s.low_hz));
    if (!std::isfinite(s.high_hz) || !(s.high_hz > s.low_hz))
        add("high_hz", fmt::format("expected a frequency above low_hz ({} Hz), got {}", s.low_hz, s.high_hz));
    if (rate > 0.0 && std::isfinite(s.high_hz) && s.high_hz >= nyquist)
        add("high_hz", fmt::format("expected a frequency below {}, got {} Hz; lower high_hz or "
                                   "resample the input to at least {} Hz",
                                   rate_note, format_hz(s.high_hz), format_hz(2.0 * s.high_hz + 1.0)));
    check_edges(s, add);
    if (s.filter_order < 1 || s.filter_order > 16)
        add("filter_order", fmt::format("expected an integer in [1, 16], got {}", s.filter_order));
    if (!std::isfinite(s.envelope_cutoff_hz) || s.envelope_cutoff_hz <= 0.0)
        add("envelope_cutoff_hz", fmt::format("expected a frequency above 0 Hz, got {}", s.envelope_cutoff_hz));
    else if (rate > 0.0 && s.envelope_cutoff_hz >= nyquist)
        add("envelope_cutoff_hz",
            fmt::format("expected a frequency below {}, got {} Hz", rate_note, format_hz(s.envelope_cutoff_hz)));
    if (s.envelope_filter_order < 1 || s.envelope_filter_order > 16)
        add("envelope_filter_order", fmt::format("expected an integer in [1, 16], got {}", s.envelope_filter_order));
    if (s.low_noise_iterations < 0 || s.low_noise_iterations > 100)
        add("low_noise_iterations", fmt::format("expected an integer in [0, 100], got {}", s.low_noise_iterations));
    if (!(rate > 0.0) && rate != 0.0)
        add("sample_rate_hz", fmt::format("expected a positive sample rate, got {}", rate));
    problems.throw_if_any();
}

// ------------------------------------------------------------- band edges

double greenwood_hz(double x) { return 165.4 * (std::pow(10.0, 2.1 * x) - 0.88); }

double greenwood_position(double frequency_hz) { return std::log10(frequency_hz / 165.4 + 0.88) / 2.1; }

std::vector<double> band_edges_hz(const VocoderSettings& s) {
    validate_settings(s, 0.0);
    if (s.spacing == BandSpacing::Explicit) return s.edges_hz;
    std::vector<double> edges(static_cast<std::size_t>(s.bands) + 1);
    const double b = s.bands;
    for (int k = 0; k <= s.bands; ++k) {
        const double t = k / b;
        switch (s.spacing) {
            case BandSpacing::Greenwood: {
                const double x0 = greenwood_position(s.low_hz);
                const double x1 = greenwood_position(s.high_hz);
                edges[k] = greenwood_hz(x0 + (x1 - x0) * t);
                break;
            }
            case BandSpacing::Log: edges[k] = s.low_hz * std::pow(s.high_hz / s.low_hz, t); break;
            case BandSpacing::Linear: edges[k] = s.low_hz + (s.high_hz - s.low_hz) * t; break;
            case BandSpacing::Explicit: break;
        }
    }
    edges.front() = s.low_hz;  // exact, whatever the rounding of the inverse map
    edges.back() = s.high_hz;
    return edges;
}

// ------------------------------------------------------------- methods text

namespace {

std::string spacing_text(const VocoderSettings& s) {
    switch (s.spacing) {
        case BandSpacing::Greenwood:
            return "Greenwood (1990) spacing: equal steps of relative cochlear place x, "
                   "F = 165.4·(10^(2.1x) − 0.88) Hz";
        case BandSpacing::Log: return "logarithmic spacing (equal frequency ratios)";
        case BandSpacing::Linear: return "linear spacing (equal widths in Hz)";
        case BandSpacing::Explicit: return "explicit band edges";
    }
    return "";
}

std::string analysis_filters_text(const VocoderSettings& s) {
    const int slope_db = 6 * s.filter_order * (s.zero_phase ? 2 : 1);
    const std::string phase = s.zero_phase
                                  ? "zero-phase (applied forward then backward in time, which squares the "
                                    "magnitude response: -6 dB at the edges, slopes doubled)"
                                  : "causal (single forward pass, non-linear phase)";
    return fmt::format("Butterworth band-pass, {}-order low-pass prototype ({} poles, {} second-order "
                       "sections per band), bilinear transform with pre-warped edges, -3 dB at the band "
                       "edges, skirts {} dB/octave; {}",
                       ordinal(s.filter_order), 2 * s.filter_order, s.filter_order, slope_db, phase);
}

// Group delay at each band centre, -dφ/dω by a central difference of the
// analysis filter's phase (the re-filter adds as much again).
std::string group_delays_text(const VocoderSettings& s, const std::vector<double>& edges,
                              const std::vector<double>& centres, double rate) {
    std::vector<double> delays_ms;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
        const Sos sos = butterworth_bandpass(s.filter_order, edges[b], edges[b + 1], rate);
        const double df = 1e-3 * (edges[b + 1] - edges[b]);
        const double dphi =
            std::arg(sos_response(sos, centres[b] + df, rate) / sos_response(sos, centres[b] - df, rate));
        delays_ms.push_back(-dphi / (2.0 * std::numbers::pi * 2.0 * df) * 1000.0);
    }
    std::string text;
    for (std::size_t b = 0; b < delays_ms.size(); ++b) text += fmt::format("{}{:.2f}", b ? ", " : "", delays_ms[b]);
    return text + " at the band centres, per analysis filter pass (causal filtering "
                  "delays narrow bands most; use zero phase to avoid it)";
}

std::string envelope_text(const VocoderSettings& s) {
    std::string method;
    switch (s.envelope) {
        case EnvelopeMethod::HalfWaveRectify: method = "half-wave rectification"; break;
        case EnvelopeMethod::FullWaveRectify: method = "full-wave rectification"; break;
        case EnvelopeMethod::Hilbert: method = "Hilbert transform (magnitude of the analytic signal, by FFT)"; break;
    }
    return fmt::format("{}, then a {}-order Butterworth low-pass at {} Hz ({} dB/octave, {}); "
                       "negative values of the smoothed envelope set to 0",
                       method, ordinal(s.envelope_filter_order), format_hz(s.envelope_cutoff_hz),
                       6 * s.envelope_filter_order * (s.zero_phase ? 2 : 1), s.zero_phase ? "zero-phase" : "causal");
}

std::string carrier_text(const VocoderSettings& s, const std::vector<double>& centres) {
    switch (s.carrier) {
        case CarrierType::Noise:
            return fmt::format("white noise (uniform amplitude distribution, xoshiro256** generator), an "
                               "independent stream per band, the same on every channel, derived from seed {}",
                               s.seed);
        case CarrierType::Sine:
            return "sine at each band's geometric centre frequency (" + join_hz(centres) +
                   " Hz), zero starting phase";
        case CarrierType::LowNoise:
            return fmt::format("low-noise noise (Pumplin 1985; Kohlrausch et al. 1997): seeded white noise "
                               "(seed {}) band-pass filtered, then {} times divided by its Hilbert envelope "
                               "and band-pass filtered again",
                               s.seed, s.low_noise_iterations);
    }
    return "";
}

std::string carrier_filtering_text(const VocoderSettings& s) {
    return fmt::format("{} before modulation; {} after modulation",
                       s.prefilter_carrier ? "band-pass filtered through its analysis band" : "not filtered",
                       s.refilter_carrier ? "band-pass filtered through its analysis band (same filter as the analysis)"
                                          : "not filtered");
}

std::string level_matching_text(const VocoderSettings& s) {
    return fmt::format("{}; {}; if the output peak would exceed full scale, the whole output is scaled down "
                       "to a peak of 0.999 (logged and reported per file), never clipped",
                       s.match_band_rms ? "each band's output RMS set to its analysis band's RMS (whole signal)"
                                        : "no per-band level matching",
                       s.match_output_rms ? "the summed output's RMS set to the input's RMS (whole signal)"
                                          : "no overall level matching");
}

// With sine carriers, an envelope cutoff above half the narrowest band's
// width may let the envelope's sidebands be resolved; empty otherwise.
std::string sine_sideband_note(const VocoderSettings& s, const std::vector<double>& edges) {
    if (s.carrier != CarrierType::Sine) return "";
    double narrowest = INFINITY;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) narrowest = std::min(narrowest, edges[b + 1] - edges[b]);
    if (!(s.envelope_cutoff_hz > narrowest / 2.0)) return "";
    return fmt::format("the envelope cutoff ({} Hz) exceeds half the narrowest band's width "
                       "({} Hz): with sine carriers, envelope sidebands may be resolved "
                       "(Cychosz et al. 2024)",
                       format_hz(s.envelope_cutoff_hz), format_hz(narrowest / 2.0));
}

}  // namespace

std::string describe(const VocoderSettings& s, double rate) {
    validate_settings(s, rate);
    const std::vector<double> edges = band_edges_hz(s);
    std::vector<double> centres;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) centres.push_back(std::sqrt(edges[b] * edges[b + 1]));
    std::string out;
    auto line = [&](std::string_view label, const std::string& text) {
        out += fmt::format("{:<22}{}\n", std::string(label) + ":", text);
    };
    line("Processing", "noise-excited channel vocoder (Shannon et al. 1995); no pre-emphasis");
    line("Sample rate", fmt::format("{} Hz (processing in double precision at the input rate)", format_hz(rate)));
    line("Channels", fmt::format("{} analysis bands, {}–{} Hz, {}", s.bands, format_hz(s.low_hz),
                                 format_hz(s.high_hz), spacing_text(s)));
    line("Band edges (Hz)", join_hz(edges));
    line("Band centres (Hz)", join_hz(centres) + " (geometric)");
    line("Analysis filters", analysis_filters_text(s));
    if (!s.zero_phase) line("Group delay (ms)", group_delays_text(s, edges, centres, rate));
    line("Envelope", envelope_text(s));
    line("Carrier", carrier_text(s, centres));
    line("Carrier filtering", carrier_filtering_text(s));
    line("Level matching", level_matching_text(s));
    line("Seed", fmt::format("{} (output is fully determined by the input, these settings and the seed)", s.seed));
    if (const std::string note = sine_sideband_note(s, edges); !note.empty()) line("Note", note);
    return out;
}

}  // namespace avsi::vocoder
