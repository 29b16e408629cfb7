// Noise-excited channel vocoder (Shannon, Zeng, Kamath, Wygonski & Ekelid
// 1995, "Speech recognition with primarily temporal cues", Science 270):
// the input is split into analysis bands, each band's temporal envelope is
// extracted and modulates a carrier (noise, sine or low-noise noise) that is
// filtered back into the same band; the bands are level-matched and summed.
// Every choice a methods section must report (Cychosz, Winn & Goupell 2024,
// "How to vocode", JASA 155) is a field of VocoderSettings and is written out
// by describe(). vocode(), vocode_stream() and vocode_channel() are the fast
// path; reference.h has the same vocoder written as its equations (the same
// output bit for bit). As a cochlear-implant simulation (pulse-train and
// Poisson pulse carriers, current spread, synthesis filters of their own
// order, an insertion-depth shift, n-of-m selection: ci_simulation.h) every
// entry point runs one whole-signal path instead.
//
// Usage:
//   avsi::vocoder::VocoderSettings settings;       // the study: 3 bands, 100–5000 Hz
//   settings.seed = 7;
//   auto result = avsi::vocoder::vocode(audio, settings);
//   avsi::write_audio("out.wav", result.audio);
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/audio_stream.h"
#include "avsi/core/error.h"

namespace avsi::vocoder {

// How the analysis band edges are placed between low_hz and high_hz.
enum class BandSpacing {
    Greenwood,  // equal steps of cochlear place, F = 165.4·(10^(2.1x) − 0.88) (Greenwood 1990)
    Log,        // equal ratios (equal octaves)
    Linear,     // equal widths in Hz
    Explicit    // the list in VocoderSettings::edges_hz
};

// How each band's temporal envelope is extracted.
enum class EnvelopeMethod {
    HalfWaveRectify,  // max(x, 0), then the envelope low-pass (Shannon et al. 1995)
    FullWaveRectify,  // |x|, then the envelope low-pass
    Hilbert           // magnitude of the analytic signal, then the envelope low-pass
};

// What the envelope modulates.
enum class CarrierType {
    Noise,          // white noise, a seeded stream per band
    Sine,           // a sine at the band's geometric centre frequency, zero phase
    LowNoise,       // noise with a flattened Hilbert envelope (Pumplin 1985; Kohlrausch et al. 1997)
    PulseTrain,     // rectangular pulses at pulse_rate_hz, phases per pulse_phase (ci_simulation.h)
    PoissonPulses,  // rectangular pulses at Poisson times of mean rate pulse_rate_hz, a seeded stream per band
    Pshc            // pulse-spreading harmonic complex (Hilkhuysen & Macherey 2014): refused, see validate_settings
};

// When each channel's pulses start within a pulse period.
enum class PulsePhase {
    Interleaved,  // channel b (from the lowest) at b/bands of the period, as CIs stimulate (no two at once)
    Simultaneous  // every channel at the start of the period
};

// How far a channel's envelope reaches the other channels' carrier bands
// (current spread; SPIRAL, Grange et al. 2017): an exponential decay with
// the distance between carrier band centres.
enum class CurrentSpread {
    None,         // each envelope drives its own carrier band only
    DbPerOctave,  // spread_slope_db per octave of centre-frequency distance
    DbPerMm       // spread_slope_db per mm of cochlear place (Greenwood 1990, 35 mm cochlea)
};

struct VocoderSettings {
    int bands = 3;                 // number of channels, [1, 64]
    double low_hz = 100.0;         // lower edge of the lowest band
    double high_hz = 5000.0;       // upper edge of the highest band; below Nyquist
    BandSpacing spacing = BandSpacing::Greenwood;
    std::vector<double> edges_hz;  // bands + 1 increasing edges, for BandSpacing::Explicit

    int filter_order = 4;          // Butterworth low-pass prototype order of each band-pass (2·order poles)
    bool zero_phase = false;       // run every filter forward and backward (doubles the slopes)

    EnvelopeMethod envelope = EnvelopeMethod::HalfWaveRectify;
    double envelope_cutoff_hz = 160.0;  // envelope low-pass cutoff
    int envelope_filter_order = 4;      // Butterworth low-pass order of the envelope filter

    CarrierType carrier = CarrierType::Noise;
    bool prefilter_carrier = false;  // band-pass the carrier before modulation as well (noise carriers)
    bool refilter_carrier = true;    // band-pass the modulated carrier through its analysis band
    int low_noise_iterations = 10;   // envelope-flattening iterations for CarrierType::LowNoise

    bool match_band_rms = true;     // each output band gets the RMS of its analysis band
    bool match_output_rms = true;   // the summed output gets the RMS of the input
    std::uint64_t seed = 1;         // carrier noise seed; output = f(input, settings, seed)

    // Cochlear-implant simulation (ci_simulation.h; any of these set runs
    // the one-thread whole-signal path, the settings above keep the fast one).
    double pulse_rate_hz = 100.0;        // pulses per second in each channel (pulse-train, poisson)
    double pulse_width_us = 100.0;       // width of each rectangular pulse
    PulsePhase pulse_phase = PulsePhase::Interleaved;  // pulse-train only
    CurrentSpread current_spread = CurrentSpread::None;
    double spread_slope_db = 8.0;        // decay per octave or per mm of the spread, > 0
    int synthesis_filter_order = 0;      // prototype order of the synthesis (carrier) filters; 0: filter_order
    double insertion_shift_mm = 0.0;     // carrier bands this many mm basal of the analysis bands (Greenwood)
    int n_of_m = 0;                      // channels kept per frame, the n of largest energy; 0: all
    double selection_frame_rate_hz = 250.0;  // frames per second of the n-of-m selection
};

// Whether the settings use a cochlear-implant simulation stage (pulse
// carriers, current spread, its own synthesis order, an insertion shift,
// n-of-m): then every entry point runs the whole-signal path of
// ci_simulation.h.
bool uses_ci_simulation(const VocoderSettings& settings);

// The memory vocoding `frames` frames of `channels` channels holds when the
// settings need the whole signal at once (the cochlear-implant simulation,
// zero-phase filters, Hilbert envelopes, the low-noise carrier keep every
// band's signal): 32 bytes per band and frame plus 130 per frame, at or
// above the peak resident memory measured for each of them
// (docs/performance.md); 0 for settings that stream in blocks. Every entry
// point refuses (InputError, field "audio") a signal whose figure exceeds
// available_memory_bytes() (core/memory.h), before it allocates.
std::uint64_t whole_signal_memory_bytes(const VocoderSettings& settings, std::size_t frames, int channels);

// Checks every field against itself and against `sample_rate_hz` (0: skip
// the checks that need a rate) and throws InputError listing every problem,
// each as "vocoder.<field>: expected …, got …". `source` names where the
// settings came from (a file or "command line") for the diagnostics.
void validate_settings(const VocoderSettings& settings, double sample_rate_hz,
                       const std::string& source = "vocoder settings");

// Greenwood's (1990) human frequency–place function, F = 165.4·(10^(2.1x) − 0.88),
// x the relative distance from the apex in [0, 1]; and its inverse.
double greenwood_hz(double relative_position);
double greenwood_position(double frequency_hz);

// The bands + 1 band edges in Hz for these settings (validated first).
std::vector<double> band_edges_hz(const VocoderSettings& settings);

// One analysis band and what the vocoder measured in it.
struct BandInfo {
    double low_hz = 0.0;
    double high_hz = 0.0;
    double centre_hz = 0.0;      // geometric centre, sqrt(low·high)
    double analysis_rms = 0.0;   // RMS of the input after the analysis filter
    double output_rms = 0.0;     // RMS of this band's output before the overall gain
    // The carrier (synthesis) band: the analysis band unless shifted.
    double carrier_low_hz = 0.0;
    double carrier_high_hz = 0.0;
    double carrier_centre_hz = 0.0;
};

// The n-of-m selection: for each frame of selection_frame_rate_hz, a bit
// per band (bit b: band b kept), for the first channel; empty without n-of-m.
using ChannelSelection = std::vector<std::uint64_t>;

struct VocoderResult {
    Audio audio;                 // same rate, channels and length as the input
    std::vector<BandInfo> bands; // for the first channel
    double output_gain_db = 0.0; // overall gain applied to match the input RMS
    double peak_before_limit = 0.0;  // largest |sample| before the anti-clipping scale
    double limit_gain_db = 0.0;  // < 0 when the output was scaled down to keep |x| ≤ 1
    ChannelSelection selection = {};  // n-of-m: the bands kept per frame
};

// Vocodes `input` (any rate; each channel separately, with its own carrier
// streams). Throws InputError for invalid settings or a rate too low for them.
// When the output would exceed full scale it is scaled down and reported in
// peak_before_limit and limit_gain_db (logged at debug level only: a caller
// that sets the level afterwards, as the stimulus builder does, need not
// tell anyone; `avsi vocode` warns).
VocoderResult vocode(const Audio& input, const VocoderSettings& settings);

// What vocode_stream measured: VocoderResult without the audio.
struct VocoderReport {
    std::vector<BandInfo> bands;  // for the first channel
    double output_gain_db = 0.0;
    double peak_before_limit = 0.0;
    double limit_gain_db = 0.0;
    ChannelSelection selection = {};   // n-of-m: the bands kept per frame
};

// vocode() from a source to a sink, block by block, the same output sample
// for sample. Level matching and the anti-clipping scale need the whole
// signal's levels before the first sample is written, so the input is read
// in up to three passes (measure; level of the sum; write): the band outputs
// of the first pass are kept up to a memory budget (96 MiB: 6.3 minutes of
// 3-band mono at 22.05 kHz) and computed again past it. Memory is bounded by
// the block length, the band count and the budget, whatever the length —
// except with zero_phase, Hilbert envelopes or low-noise carriers, which
// need the whole signal at once (in memory).
VocoderReport vocode_stream(AudioSource& input, AudioSink& output, const VocoderSettings& settings);

// One channel's output and what was measured on the way.
struct ChannelResult {
    std::vector<double> samples;   // summed bands after the overall gain (no anti-clipping scale)
    std::vector<BandInfo> bands;
    double output_gain_db = 0.0;   // overall gain applied to match the input RMS
    // Each band's output before the overall gain, when asked for.
    std::vector<std::vector<double>> band_signals;
    ChannelSelection selection = {};    // n-of-m: the bands kept per frame
};

// Vocodes one channel of samples at `sample_rate_hz`; `channel` selects the
// carrier noise streams ("channel<c>/band<b>" derived from the seed).
ChannelResult vocode_channel(std::span<const double> samples, double sample_rate_hz,
                             const VocoderSettings& settings, int channel = 0,
                             bool keep_band_signals = false);

namespace detail {
// vocode_channel with the streaming block length given (for tests: any
// block length must give the same output).
ChannelResult vocode_channel_in_blocks(std::span<const double> samples, double sample_rate_hz,
                                       const VocoderSettings& settings, int channel, bool keep_band_signals,
                                       std::size_t block_frames);

// The block length, the memory kept from the first pass (band outputs,
// 4 bytes per band, channel and frame; past it they are computed again) and
// the threads of the filter pipeline (2: steps 1–2 and 3–4 of the channel
// vocoder on two threads, a piece of 4096 frames apart, when a block holds
// more than one piece, and pass 3's writing beside its sums; the output is
// the same with 1, which vocode() and the vocode_stream above use).
struct StreamLimits {
    std::size_t block_frames = 32768;
    std::size_t store_bytes = std::size_t{96} << 20;
    unsigned threads = 2;
};
// vocode_stream with the limits given (for tests: any limits must give the
// same output).
VocoderReport vocode_stream(AudioSource& input, AudioSink& output, const VocoderSettings& settings,
                            const StreamLimits& limits);
}  // namespace detail

// A methods-section description of the processing for this rate: band
// edges, filter type, order and slopes, phase, envelope method, cutoff and
// filter, carrier and its filtering, level matching, seed, sample rate
// (the checklist of Cychosz, Winn & Goupell 2024). One item per line.
std::string describe(const VocoderSettings& settings, double sample_rate_hz);

// Names used on the command line and in reports, and their parsers (which
// throw InputError naming `field` and the accepted values).
std::string to_string(BandSpacing spacing);
std::string to_string(EnvelopeMethod method);
std::string to_string(CarrierType carrier);
std::string to_string(PulsePhase phase);
std::string to_string(CurrentSpread spread);
BandSpacing parse_band_spacing(const std::string& text, const std::string& field = "spacing");
EnvelopeMethod parse_envelope_method(const std::string& text, const std::string& field = "envelope");
CarrierType parse_carrier_type(const std::string& text, const std::string& field = "carrier");
PulsePhase parse_pulse_phase(const std::string& text, const std::string& field = "pulse_phase");
CurrentSpread parse_current_spread(const std::string& text, const std::string& field = "current_spread");

// The carrier band edges in Hz: band_edges_hz shifted basally by
// insertion_shift_mm, x' = x + shift / 35 mm, F = greenwood_hz(x').
std::vector<double> carrier_edges_hz(const VocoderSettings& settings);

// The n-of-m selection as CSV: frame,start_s,bands (the kept bands'
// indices, from 0, separated by spaces), one line per frame.
std::string selection_csv(const ChannelSelection& selection, double frame_rate_hz);

}  // namespace avsi::vocoder
