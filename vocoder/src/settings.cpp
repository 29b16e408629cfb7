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

// Greenwood's map spans x in [0, 1] of a 35 mm cochlea.
constexpr double kCochleaLengthMm = 35.0;

// band_edges_hz without the validation (for validate_settings itself).
std::vector<double> band_edges_unchecked(const VocoderSettings& s);

// Edges moved `shift_mm` basally: x' = x + shift / 35 mm (Greenwood 1990).
std::vector<double> shifted_edges(std::vector<double> edges, double shift_mm) {
    if (shift_mm == 0.0) return edges;
    for (double& e : edges) e = greenwood_hz(greenwood_position(e) + shift_mm / kCochleaLengthMm);
    return edges;
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
        case CarrierType::PulseTrain: return "pulse-train";
        case CarrierType::PoissonPulses: return "poisson";
        case CarrierType::Pshc: return "pshc";
    }
    return "?";
}

std::string to_string(PulsePhase phase) {
    switch (phase) {
        case PulsePhase::Interleaved: return "interleaved";
        case PulsePhase::Simultaneous: return "simultaneous";
    }
    return "?";
}

std::string to_string(CurrentSpread spread) {
    switch (spread) {
        case CurrentSpread::None: return "none";
        case CurrentSpread::DbPerOctave: return "db-per-octave";
        case CurrentSpread::DbPerMm: return "db-per-mm";
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
    return parse_enum(text, field,
                      {CarrierType::Noise, CarrierType::Sine, CarrierType::LowNoise, CarrierType::PulseTrain,
                       CarrierType::PoissonPulses, CarrierType::Pshc});
}

PulsePhase parse_pulse_phase(const std::string& text, const std::string& field) {
    return parse_enum(text, field, {PulsePhase::Interleaved, PulsePhase::Simultaneous});
}

CurrentSpread parse_current_spread(const std::string& text, const std::string& field) {
    return parse_enum(text, field, {CurrentSpread::None, CurrentSpread::DbPerOctave, CurrentSpread::DbPerMm});
}

bool uses_ci_simulation(const VocoderSettings& s) {
    return s.carrier == CarrierType::PulseTrain || s.carrier == CarrierType::PoissonPulses ||
           s.carrier == CarrierType::Pshc || s.current_spread != CurrentSpread::None ||
           (s.synthesis_filter_order != 0 && s.synthesis_filter_order != s.filter_order) ||
           s.insertion_shift_mm != 0.0 || s.n_of_m != 0;
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

// The pulse carriers' rate and width, and interleaved pulses that fit in a period.
void check_pulses(const VocoderSettings& s, double rate, const AddProblem& add) {
    if (!std::isfinite(s.pulse_rate_hz) || s.pulse_rate_hz <= 0.0 || s.pulse_rate_hz > 20000.0) {
        add("pulse_rate_hz", fmt::format("expected a rate in (0, 20000] pulses/s, got {}", s.pulse_rate_hz));
        return;
    }
    const double period_us = 1e6 / s.pulse_rate_hz;
    if (!std::isfinite(s.pulse_width_us) || s.pulse_width_us <= 0.0 || s.pulse_width_us >= period_us) {
        add("pulse_width_us", fmt::format("expected a width above 0 and below the pulse period ({:.1f} µs at {} "
                                          "pulses/s), got {}",
                                          period_us, s.pulse_rate_hz, s.pulse_width_us));
        return;
    }
    if (s.carrier == CarrierType::PulseTrain && s.pulse_phase == PulsePhase::Interleaved && s.bands >= 1 &&
        s.bands * s.pulse_width_us > period_us)
        add("pulse_width_us", fmt::format("expected interleaved pulses that do not overlap: bands × width "
                                          "({} × {} µs) at most the period ({:.1f} µs); lower the width or the "
                                          "rate, or set pulse_phase = \"simultaneous\"",
                                          s.bands, s.pulse_width_us, period_us));
    if (rate > 0.0 && s.pulse_rate_hz >= rate / 2.0)
        add("pulse_rate_hz", fmt::format("expected a rate below half the sample rate ({} Hz), got {}",
                                         format_hz(rate / 2.0), s.pulse_rate_hz));
}

// The stages of the cochlear-implant simulation (ci_simulation.h).
void check_ci_stages(const VocoderSettings& s, double rate, const AddProblem& add) {
    if (s.carrier == CarrierType::Pshc)
        add("carrier", "the pulse-spreading harmonic complex (pshc, Hilkhuysen & Macherey 2014) is not "
                       "available: its component phases and pulse-spreading order could not be checked "
                       "against the paper; expected one of noise, sine, low-noise, pulse-train, poisson");
    check_pulses(s, rate, add);
    if (!std::isfinite(s.spread_slope_db) || s.spread_slope_db <= 0.0 || s.spread_slope_db > 1000.0)
        add("spread_slope_db",
            fmt::format("expected a decay in (0, 1000] dB per octave or per mm, got {}", s.spread_slope_db));
    if (s.synthesis_filter_order < 0 || s.synthesis_filter_order > 16)
        add("synthesis_filter_order",
            fmt::format("expected 0 (the analysis order) or an integer in [1, 16], got {}", s.synthesis_filter_order));
    if (!std::isfinite(s.insertion_shift_mm) || s.insertion_shift_mm < -10.0 || s.insertion_shift_mm > 20.0)
        add("insertion_shift_mm", fmt::format("expected a shift in [-10, 20] mm, got {}", s.insertion_shift_mm));
    if (s.n_of_m < 0 || s.n_of_m > std::max(s.bands, 0))
        add("n_of_m", fmt::format("expected 0 (every channel) or at most the {} bands, got {} selected "
                                  "channels",
                                  s.bands, s.n_of_m));
    if (!std::isfinite(s.selection_frame_rate_hz) || s.selection_frame_rate_hz <= 0.0 ||
        (rate > 0.0 && s.selection_frame_rate_hz > rate))
        add("selection_frame_rate_hz", fmt::format("expected a frame rate above 0 and at most the sample rate, "
                                                   "got {}",
                                                   s.selection_frame_rate_hz));
}

// The carrier bands once shifted: within Greenwood's map and below Nyquist;
// with a periodic pulse train, each must hold one of its harmonics.
void check_carrier_bands(const VocoderSettings& s, double rate, const AddProblem& add) {
    const std::vector<double> edges = band_edges_unchecked(s);
    const double shift = s.insertion_shift_mm / kCochleaLengthMm;
    const double x_low = greenwood_position(edges.front()) + shift;
    const double x_high = greenwood_position(edges.back()) + shift;
    if (s.insertion_shift_mm != 0.0 && (x_low < 0.0 || x_high > 1.0)) {
        add("insertion_shift_mm", fmt::format("expected carrier bands within Greenwood's map (20–20677 Hz): "
                                              "{} mm moves {}–{} Hz to {}–{} Hz",
                                              s.insertion_shift_mm, format_hz(edges.front()),
                                              format_hz(edges.back()), format_hz(greenwood_hz(x_low)),
                                              format_hz(greenwood_hz(x_high))));
        return;
    }
    const std::vector<double> carrier = shifted_edges(edges, s.insertion_shift_mm);
    if (rate > 0.0 && s.insertion_shift_mm != 0.0 && carrier.back() >= rate / 2.0)
        add("insertion_shift_mm", fmt::format("expected carrier bands below the Nyquist frequency ({} Hz), "
                                              "got a highest carrier edge of {} Hz",
                                              format_hz(rate / 2.0), format_hz(carrier.back())));
    if (s.carrier != CarrierType::PulseTrain) return;
    for (std::size_t b = 0; b + 1 < carrier.size(); ++b)
        if (std::floor(carrier[b + 1] / s.pulse_rate_hz) < std::ceil(carrier[b] / s.pulse_rate_hz)) {
            add("pulse_rate_hz", fmt::format("expected every carrier band to hold a harmonic of the pulse rate, "
                                             "got band {} ({}–{} Hz) with none of {} Hz",
                                             b, format_hz(carrier[b]), format_hz(carrier[b + 1]),
                                             s.pulse_rate_hz));
            return;
        }
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
    check_ci_stages(s, rate, add);
    if (problems.empty()) check_carrier_bands(s, rate, add);
    problems.throw_if_any();
}

// ------------------------------------------------------------- band edges

double greenwood_hz(double x) { return 165.4 * (std::pow(10.0, 2.1 * x) - 0.88); }

double greenwood_position(double frequency_hz) { return std::log10(frequency_hz / 165.4 + 0.88) / 2.1; }

std::vector<double> band_edges_hz(const VocoderSettings& s) {
    validate_settings(s, 0.0);
    return band_edges_unchecked(s);
}

std::vector<double> carrier_edges_hz(const VocoderSettings& s) {
    validate_settings(s, 0.0);
    return shifted_edges(band_edges_unchecked(s), s.insertion_shift_mm);
}

namespace {

std::vector<double> band_edges_unchecked(const VocoderSettings& s) {
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

}  // namespace

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

// The pulse train's rate, width and each band's phase (its first onset).
std::string pulse_train_text(const VocoderSettings& s) {
    const double period_ms = 1000.0 / s.pulse_rate_hz;
    std::string offsets;
    for (int b = 0; b < s.bands; ++b) {
        const double offset = s.pulse_phase == PulsePhase::Interleaved ? period_ms * b / s.bands : 0.0;
        offsets += fmt::format("{}{:.3f}", b ? ", " : "", offset);
    }
    return fmt::format("rectangular pulse train, {} pulses/s in every band (period {:.3f} ms), pulses {} µs wide; "
                       "{}; first onsets {} ms; each sample holds its overlap with a pulse (exact onsets and "
                       "widths at any sample rate)",
                       s.pulse_rate_hz, period_ms, s.pulse_width_us,
                       s.pulse_phase == PulsePhase::Interleaved
                           ? "interleaved: band b (from the lowest) fires b/bands of a period after band 0, "
                             "no two bands at once, as continuous interleaved sampling stimulates"
                           : "simultaneous: every band fires at the same instants",
                       offsets);
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
        case CarrierType::PulseTrain: return pulse_train_text(s);
        case CarrierType::PoissonPulses:
            return fmt::format("rectangular pulses {} µs wide at the times of a Poisson process of mean rate {} "
                               "pulses/s (exponential intervals), independent in each band: streams "
                               "\"channel0/band<b>/poisson\" derived from seed {}; each sample holds its overlap "
                               "with a pulse (exact onsets and widths at any sample rate)",
                               s.pulse_width_us, s.pulse_rate_hz, s.seed);
        case CarrierType::Pshc: return "pulse-spreading harmonic complex (refused)";
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

// ------------------------------------------------------------- CI simulation text

std::vector<double> geometric_centres(const std::vector<double>& edges) {
    std::vector<double> centres;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) centres.push_back(std::sqrt(edges[b] * edges[b + 1]));
    return centres;
}

std::string synthesis_filters_text(const VocoderSettings& s) {
    const int order = s.synthesis_filter_order == 0 ? s.filter_order : s.synthesis_filter_order;
    return fmt::format("Butterworth band-pass on each carrier band, {}-order low-pass prototype ({} poles), skirts "
                       "{} dB/octave{}; {}",
                       ordinal(order), 2 * order, 6 * order * (s.zero_phase ? 2 : 1),
                       s.synthesis_filter_order == 0 ? " (the analysis order)" : " (set apart from the analysis)",
                       s.zero_phase ? "zero-phase" : "causal");
}

// The carrier bands and the frequency-to-place mismatch of the shift.
std::string insertion_text(const VocoderSettings& s, const std::vector<double>& centres,
                           const std::vector<double>& carrier_centres) {
    if (s.insertion_shift_mm == 0.0) return "none: each carrier band is its analysis band";
    std::string mismatch;
    for (std::size_t b = 0; b < centres.size(); ++b)
        mismatch += fmt::format("{}{:+.2f}", b ? ", " : "", std::log2(carrier_centres[b] / centres[b]));
    return fmt::format("carrier bands {} mm {} of the analysis bands along the cochlea (Greenwood 1990, 35 mm: "
                       "x' = x + {:.4f}), simulating a {} electrode array; frequency-to-place mismatch at the band "
                       "centres {} octaves",
                       std::abs(s.insertion_shift_mm), s.insertion_shift_mm > 0 ? "basal" : "apical",
                       s.insertion_shift_mm / kCochleaLengthMm,
                       s.insertion_shift_mm > 0 ? "shallowly inserted" : "deeply inserted", mismatch);
}

// The spread's weights from band 0 to the others, in dB.
std::string current_spread_text(const VocoderSettings& s, const std::vector<double>& carrier_centres) {
    if (s.current_spread == CurrentSpread::None) return "none: each channel's envelope drives its own carrier band";
    const bool per_mm = s.current_spread == CurrentSpread::DbPerMm;
    std::string weights;
    for (std::size_t k = 0; k < carrier_centres.size(); ++k) {
        const double distance = per_mm ? kCochleaLengthMm * std::abs(greenwood_position(carrier_centres[k]) -
                                                                     greenwood_position(carrier_centres[0]))
                                       : std::abs(std::log2(carrier_centres[k] / carrier_centres[0]));
        weights += fmt::format("{}{:.1f}", k ? ", " : "", -s.spread_slope_db * distance);
    }
    return fmt::format("each channel's envelope also drives every other carrier band, attenuated by {} dB per {} "
                       "of distance between the carrier band centres (an exponential decay of current, as in SPIRAL, "
                       "Grange et al. 2017); each contribution's level is set relative to the channel's level-matched "
                       "level in its own band, and the contributions to a band add; band 0 reaches the bands at {} dB",
                       s.spread_slope_db, per_mm ? "mm of cochlear place (Greenwood 1990, 35 mm)" : "octave", weights);
}

std::string selection_text(const VocoderSettings& s, double rate) {
    if (s.n_of_m == 0) return fmt::format("none: all {} channels in every frame", s.bands);
    return fmt::format("{}-of-{}: in each frame of 1/{} s ({:.1f} samples), the {} bands of largest analysis energy "
                       "(sum of squares of the band-passed input over the frame; ties to the lower band) keep their "
                       "envelope, the others' envelope is 0; band gains are measured before the selection; the "
                       "bands kept in each frame are logged",
                       s.n_of_m, s.bands, s.selection_frame_rate_hz, rate / s.selection_frame_rate_hz, s.n_of_m);
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
    const bool ci = uses_ci_simulation(s);
    const std::vector<double> carrier_centres = geometric_centres(carrier_edges_hz(s));
    line("Processing", ci ? "channel vocoder (Shannon et al. 1995) as a cochlear-implant simulation; no pre-emphasis"
                          : "noise-excited channel vocoder (Shannon et al. 1995); no pre-emphasis");
    line("Sample rate", fmt::format("{} Hz (processing in double precision at the input rate)", format_hz(rate)));
    line("Channels", fmt::format("{} analysis bands, {}–{} Hz, {}", s.bands, format_hz(s.low_hz),
                                 format_hz(s.high_hz), spacing_text(s)));
    line("Band edges (Hz)", join_hz(edges));
    line("Band centres (Hz)", join_hz(centres) + " (geometric)");
    line("Analysis filters", analysis_filters_text(s));
    if (!s.zero_phase) line("Group delay (ms)", group_delays_text(s, edges, centres, rate));
    line("Envelope", envelope_text(s));
    if (ci) {
        line("Carrier bands (Hz)", join_hz(carrier_edges_hz(s)) + " (edges); centres " + join_hz(carrier_centres));
        line("Insertion shift", insertion_text(s, centres, carrier_centres));
        line("Synthesis filters", synthesis_filters_text(s));
        line("Current spread", current_spread_text(s, carrier_centres));
        line("Channel selection", selection_text(s, rate));
    }
    line("Carrier", carrier_text(s, ci ? carrier_centres : centres));
    line("Carrier filtering", carrier_filtering_text(s));
    line("Level matching", level_matching_text(s));
    line("Seed", fmt::format("{} (output is fully determined by the input, these settings and the seed)", s.seed));
    if (const std::string note = sine_sideband_note(s, edges); !note.empty()) line("Note", note);
    return out;
}

std::string selection_csv(const ChannelSelection& selection, double frame_rate_hz) {
    std::string out = "frame,start_s,bands\n";
    for (std::size_t f = 0; f < selection.size(); ++f) {
        out += fmt::format("{},{:.6f},", f, static_cast<double>(f) / frame_rate_hz);
        bool first = true;
        for (int b = 0; b < 64; ++b)
            if ((selection[f] >> b) & 1u) {
                out += fmt::format("{}{}", first ? "" : " ", b);
                first = false;
            }
        out += "\n";
    }
    return out;
}

}  // namespace avsi::vocoder
