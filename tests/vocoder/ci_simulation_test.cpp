// The cochlear-implant simulation (avsi/vocoder/ci_simulation.h) against
// values computed here from the definitions: a pulse-train vocoder's band
// outputs are pulse trains at the set rate, interleaved by b/bands of a
// period when asked and simultaneous otherwise; Poisson pulses come at the
// mean rate from seeded streams; current spread of S dB/octave (or dB/mm)
// puts a neighbour band S·distance below the band of a single-band input;
// the synthesis filters' own order sets the output's slopes; a 4 mm shift
// moves the carrier centres to Greenwood's (1990) prediction (and a sine
// carrier's output there); n-of-m keeps exactly the n bands of largest
// energy in every frame; impossible settings are refused by name; and every
// entry point (vocode, vocode_channel, vocode_stream) gives the same output.
#include "avsi/vocoder/ci_simulation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <vector>

#include "avsi/core/audio_stream.h"
#include "avsi/core/rng.h"
#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/reference.h"
#include "avsi/vocoder/vocoder.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

using testing::rms;
constexpr double kPi = std::numbers::pi;

// Greenwood (1990), written here: F = 165.4·(10^(2.1x) − 0.88), 35 mm.
double place_hz(double x) { return 165.4 * (std::pow(10.0, 2.1 * x) - 0.88); }
double place_of(double hz) { return std::log10(hz / 165.4 + 0.88) / 2.1; }

// Sines of the given amplitudes at the given frequencies, `seconds` long.
std::vector<double> sines(const std::vector<double>& hz, const std::vector<double>& amplitude, double rate,
                          double seconds) {
    std::vector<double> x(static_cast<std::size_t>(rate * seconds), 0.0);
    for (std::size_t n = 0; n < x.size(); ++n)
        for (std::size_t i = 0; i < hz.size(); ++i) x[n] += amplitude[i] * std::sin(2 * kPi * hz[i] * n / rate);
    return x;
}

std::vector<double> centres_of(const VocoderSettings& s) {
    const std::vector<double> e = band_edges_hz(s);
    std::vector<double> c;
    for (std::size_t b = 0; b + 1 < e.size(); ++b) c.push_back(std::sqrt(e[b] * e[b + 1]));
    return c;
}

double db(double ratio) { return 20.0 * std::log10(ratio); }

// The lag in (period/2, 3·period/2) at which y²'s autocorrelation peaks.
std::size_t repetition_lag(const std::vector<double>& y, double period) {
    std::vector<double> e(y.size());
    for (std::size_t n = 0; n < y.size(); ++n) e[n] = y[n] * y[n];
    std::size_t best = 0;
    double best_value = -1.0;
    for (auto lag = static_cast<std::size_t>(period / 2); lag < static_cast<std::size_t>(1.5 * period); ++lag) {
        double sum = 0.0;
        for (std::size_t n = 0; n + lag < e.size(); ++n) sum += e[n] * e[n + lag];
        if (sum > best_value) best_value = sum, best = lag;
    }
    return best;
}

// Where in the period y²'s energy is, as a fraction of a period in [0, 1):
// the phase of Σ y[n]²·e^{−j2πn/period}, and how concentrated it is (the
// magnitude over Σ y²: 1 for pulses, 0 for a steady signal).
std::pair<double, double> pulse_phase(const std::vector<double>& y, double period, std::size_t from) {
    std::complex<double> sum = 0.0;
    double total = 0.0;
    for (std::size_t n = from; n < y.size(); ++n) {
        sum += y[n] * y[n] * std::polar(1.0, -2 * kPi * static_cast<double>(n) / period);
        total += y[n] * y[n];
    }
    double phase = -std::arg(sum) / (2 * kPi);
    phase -= std::floor(phase);
    return {phase, std::abs(sum) / total};
}

// The circular distance between two fractions of a period.
double phase_distance(double a, double b) {
    const double d = std::abs(a - b);
    return std::min(d, 1.0 - d);
}

VocoderSettings pulse_settings(PulsePhase phase) {
    VocoderSettings s;
    s.bands = 4;
    s.low_hz = 300;
    s.high_hz = 5000;
    s.carrier = CarrierType::PulseTrain;
    s.pulse_rate_hz = 250;
    s.pulse_width_us = 100;
    s.pulse_phase = phase;
    s.zero_phase = true;  // no group delay: the pulses stay where the carrier put them
    return s;
}

TEST(CiSimulation, PulseTrainBandsArePulseTrainsAtTheRateInterleaved) {
    const double rate = 22050;
    const VocoderSettings s = pulse_settings(PulsePhase::Interleaved);
    const std::vector<double> c = centres_of(s);
    const auto x = sines(c, {0.1, 0.1, 0.1, 0.1}, rate, 1.0);
    const ChannelResult r = vocode_channel(x, rate, s, 0, true);
    ASSERT_EQ(r.band_signals.size(), 4u);
    const double period = rate / s.pulse_rate_hz;  // 88.2 samples
    const double centre_of_pulse = s.pulse_width_us * 1e-6 / 2 * s.pulse_rate_hz;
    for (std::size_t b = 0; b < 4; ++b) {
        SCOPED_TRACE("band " + std::to_string(b));
        const std::size_t lag = repetition_lag(r.band_signals[b], period);
        EXPECT_LE(std::abs(static_cast<double>(lag) - period), 1.0) << "repeats every " << lag << " samples";
        const auto [phase, concentration] = pulse_phase(r.band_signals[b], period, 2205);
        EXPECT_GT(concentration, 0.1) << "energy spread over the period: not a pulse train";
        EXPECT_LT(phase_distance(phase, b / 4.0 + centre_of_pulse), 0.02)
            << "pulses at " << phase << " of the period, expected " << b / 4.0 + centre_of_pulse;
    }
}

TEST(CiSimulation, PulseTrainBandsAreSimultaneousWhenAsked) {
    const double rate = 22050;
    const VocoderSettings s = pulse_settings(PulsePhase::Simultaneous);
    const auto x = sines(centres_of(s), {0.1, 0.1, 0.1, 0.1}, rate, 1.0);
    const ChannelResult r = vocode_channel(x, rate, s, 0, true);
    const double period = rate / s.pulse_rate_hz;
    const double first = pulse_phase(r.band_signals[0], period, 2205).first;
    for (std::size_t b = 1; b < 4; ++b)
        EXPECT_LT(phase_distance(pulse_phase(r.band_signals[b], period, 2205).first, first), 0.02) << "band " << b;
}

TEST(CiSimulation, PulseCarrierHoldsEachPulsesAreaAtAnyRate) {
    VocoderSettings s = pulse_settings(PulsePhase::Interleaved);
    // 100 µs at 22050 Hz is 2.205 samples: the area of every pulse is its
    // width whatever its onset, and the sum over 1 s is rate × width.
    const std::vector<double> c = pulse_carrier(s, 22050, 1, 0, 22050);
    double area = 0.0;
    for (double v : c) area += v;
    EXPECT_NEAR(area, 250 * 2.205, 1e-9);
    EXPECT_DOUBLE_EQ(*std::max_element(c.begin(), c.end()), 1.0);
    // Band 1's first pulse starts a quarter period (22.05 samples) in.
    EXPECT_EQ(c[21], 0.0);
    EXPECT_NEAR(c[22], 0.95, 1e-12);
    EXPECT_NEAR(c[23], 1.0, 1e-12);
}

TEST(CiSimulation, PoissonPulsesComeAtTheMeanRateFromSeededStreams) {
    VocoderSettings s;
    s.carrier = CarrierType::PoissonPulses;
    s.pulse_rate_hz = 100;
    s.pulse_width_us = 20;  // under a sample at 16 kHz: each pulse's area stays in one or two samples
    const double rate = 16000;
    const auto count_onsets = [](const std::vector<double>& c) {
        std::size_t onsets = 0;
        for (std::size_t n = 0; n < c.size(); ++n) onsets += c[n] > 0.0 && (n == 0 || c[n - 1] == 0.0);
        return onsets;
    };
    const std::vector<double> a = pulse_carrier(s, rate, 0, 0, 16000 * 20);
    const std::size_t onsets = count_onsets(a);
    // 2000 expected in 20 s; the count is Poisson, sd 45: within 4 sd.
    EXPECT_NEAR(static_cast<double>(onsets), 2000.0, 180.0);
    EXPECT_EQ(pulse_carrier(s, rate, 0, 0, 16000 * 20), a);      // seeded
    EXPECT_NE(pulse_carrier(s, rate, 1, 0, 16000 * 20), a);      // a stream per band
    s.seed = 2;
    EXPECT_NE(pulse_carrier(s, rate, 0, 0, 16000 * 20), a);      // and per seed
}

// A single-band input: a sine at band 2's centre; steep zero-phase analysis
// filters keep it out of the other bands (below −90 dB), so every other
// band's output is band 2's current spread.
ChannelResult single_band_run(CurrentSpread spread, double slope_db, CarrierType carrier) {
    VocoderSettings s;
    s.bands = 6;
    s.low_hz = 250;
    s.high_hz = 4000;
    s.spacing = BandSpacing::Log;  // 2/3 octave per band
    s.filter_order = 8;
    s.zero_phase = true;
    s.carrier = carrier;
    s.current_spread = spread;
    s.spread_slope_db = slope_db;
    auto x = sines({centres_of(s)[2]}, {0.1}, 16000, 2.0);
    // 100 ms raised-cosine ramps: no broadband onset for the other bands.
    for (std::size_t n = 0; n < 1600; ++n) {
        const double ramp = 0.5 - 0.5 * std::cos(kPi * n / 1600.0);
        x[n] *= ramp;
        x[x.size() - 1 - n] *= ramp;
    }
    return vocode_channel(x, 16000, s, 0, true);
}

TEST(CiSimulation, CurrentSpreadPerOctaveSetsTheNeighbourBandLevels) {
    for (const double slope : {4.0, 8.0, 16.0})
        for (const CarrierType carrier : {CarrierType::Noise, CarrierType::Sine}) {
            SCOPED_TRACE(std::to_string(slope) + " dB/octave, " + to_string(carrier));
            const ChannelResult r = single_band_run(CurrentSpread::DbPerOctave, slope, carrier);
            const double own = rms(r.band_signals[2]);
            for (int k = 0; k < 6; ++k)
                EXPECT_NEAR(db(rms(r.band_signals[k]) / own), -slope * (2.0 / 3.0) * std::abs(k - 2), 0.1)
                    << "band " << k;
        }
}

TEST(CiSimulation, CurrentSpreadPerMmFollowsGreenwoodsPlace) {
    const ChannelResult r = single_band_run(CurrentSpread::DbPerMm, 2.0, CarrierType::Noise);
    const double own = rms(r.band_signals[2]);
    for (int k = 0; k < 6; ++k) {
        const double mm = 35.0 * std::abs(place_of(r.bands[k].carrier_centre_hz) - place_of(r.bands[2].carrier_centre_hz));
        EXPECT_NEAR(db(rms(r.band_signals[k]) / own), -2.0 * mm, 0.1) << "band " << k << " at " << mm << " mm";
    }
}

TEST(CiSimulation, WithoutSpreadTheOtherBandsStaySilent) {
    const ChannelResult r = single_band_run(CurrentSpread::None, 8.0, CarrierType::Noise);
    const double own = rms(r.band_signals[2]);
    for (int k : {0, 1, 3, 4, 5}) EXPECT_LT(db(rms(r.band_signals[k]) / own), -60.0) << "band " << k;
}

// The power of y in a 1/12-octave band around `hz` (an 8th-order band-pass).
double level_near(const std::vector<double>& y, double hz, double rate) {
    const Sos sos = butterworth_bandpass(8, hz * std::pow(2.0, -1.0 / 24), hz * std::pow(2.0, 1.0 / 24), rate);
    const SosBank bank({sos});
    std::vector<double> rows(y.size() * bank.stride(), 0.0);
    for (std::size_t n = 0; n < y.size(); ++n) rows[n * bank.stride()] = y[n];
    bank.process(rows.data(), y.size(), false);
    double sum = 0.0;
    for (std::size_t n = y.size() / 10; n < y.size(); ++n) sum += rows[n * bank.stride()] * rows[n * bank.stride()];
    return 10.0 * std::log10(sum);
}

// A digital Butterworth band-pass's attenuation (bilinear transform with
// pre-warped edges), from its analogue prototype: 10·log10(1 + Ω^2N).
double butterworth_attenuation_db(int order, double lo, double hi, double f, double rate) {
    const double w = std::tan(kPi * f / rate), w1 = std::tan(kPi * lo / rate), w2 = std::tan(kPi * hi / rate);
    const double omega = (w * w - w1 * w2) / (w * (w2 - w1));
    return 10.0 * std::log10(1.0 + std::pow(std::abs(omega), 2.0 * order));
}

TEST(CiSimulation, SynthesisFiltersHaveTheirOwnSlopes) {
    const double rate = 32000;
    Rng rng(3);
    std::vector<double> x(static_cast<std::size_t>(rate * 8));
    for (double& v : x) v = 0.1 * rng.normal();
    for (const int order : {2, 6}) {
        SCOPED_TRACE("synthesis order " + std::to_string(order));
        VocoderSettings s;
        s.bands = 1;
        s.low_hz = 1000;
        s.high_hz = 2000;
        s.synthesis_filter_order = order;
        s.filter_order = order == 2 ? 6 : 2;  // set apart from the analysis order
        const ChannelResult r = vocode_channel(x, rate, s);
        const double pass = level_near(r.samples, std::sqrt(2000.0 * 1000.0), rate);
        // The modulated noise is white: the output's spectrum is the filter's
        // response; a band of constant relative width at f holds f/fc times
        // the bandwidth of the one at the centre fc.
        for (const double f : {3000.0, 4000.0, 6000.0})
            EXPECT_NEAR(pass - level_near(r.samples, f, rate),
                        butterworth_attenuation_db(order, 1000, 2000, f, rate) -
                            10.0 * std::log10(f / std::sqrt(2000.0 * 1000.0)),
                        1.0)
                << f << " Hz";
    }
}

TEST(CiSimulation, FourMmShiftMovesCarrierCentresToGreenwood) {
    VocoderSettings s;
    s.bands = 8;
    s.carrier = CarrierType::Sine;
    s.insertion_shift_mm = 4.0;
    const double rate = 22050;
    const ChannelResult r = vocode_channel(testing::speech_like(rate, 1.0), rate, s, 0, true);
    const std::vector<double> e = band_edges_hz(s);
    for (std::size_t b = 0; b < 8; ++b) {
        SCOPED_TRACE("band " + std::to_string(b));
        const double lo = place_hz(place_of(e[b]) + 4.0 / 35.0), hi = place_hz(place_of(e[b + 1]) + 4.0 / 35.0);
        EXPECT_NEAR(r.bands[b].carrier_low_hz, lo, 1e-6 * lo);
        EXPECT_NEAR(r.bands[b].carrier_high_hz, hi, 1e-6 * hi);
        EXPECT_NEAR(r.bands[b].carrier_centre_hz, std::sqrt(lo * hi), 1e-6 * hi);
        EXPECT_NEAR(r.bands[b].centre_hz, std::sqrt(e[b] * e[b + 1]), 1e-9 * hi);  // the analysis stays
        // The band's output is its carrier: the sine at the shifted centre
        // (its zero crossings, 2·f per second).
        const std::vector<double>& y = r.band_signals[b];
        std::size_t crossings = 0;
        for (std::size_t n = 2205; n + 1 < y.size(); ++n) crossings += (y[n] < 0.0) != (y[n + 1] < 0.0);
        const double seconds = (y.size() - 2206) / rate;
        EXPECT_NEAR(crossings / (2.0 * seconds), std::sqrt(lo * hi), 0.01 * std::sqrt(lo * hi));
    }
}

TEST(CiSimulation, NOfMKeepsExactlyTheLargestBandsPerFrame) {
    VocoderSettings s;
    s.bands = 8;
    s.filter_order = 8;
    s.zero_phase = true;
    s.n_of_m = 3;
    s.selection_frame_rate_hz = 10;  // 100 ms frames, one per segment below
    s.synthesis_filter_order = 2;    // short ringing of the narrow low bands past a frame
    const double rate = 16000;
    const std::vector<double> c = centres_of(s);
    // Twelve 100 ms segments; in each, the bands' amplitudes are 2^rank for
    // a seeded permutation of ranks 0..7.
    Rng rng(11);
    std::vector<double> x;
    std::vector<std::vector<int>> ranks;
    for (int seg = 0; seg < 12; ++seg) {
        std::vector<int> rank(8);
        for (int b = 0; b < 8; ++b) rank[b] = b;
        for (int i = 7; i > 0; --i) std::swap(rank[i], rank[rng.uniform_int(i + 1)]);
        std::vector<double> amplitude;
        for (int b = 0; b < 8; ++b) amplitude.push_back(0.002 * std::pow(2.0, rank[b]));
        std::vector<double> part(1600);  // the sines run on across segments
        for (std::size_t n = 0; n < part.size(); ++n) {
            double v = 0.0;
            const double t = (x.size() + n) / rate;
            for (int b = 0; b < 8; ++b) v += amplitude[b] * std::sin(2 * kPi * c[b] * t);
            part[n] = v;
        }
        x.insert(x.end(), part.begin(), part.end());
        ranks.push_back(rank);
    }
    const ChannelResult r = vocode_channel(x, rate, s, 0, true);
    ASSERT_EQ(r.selection.size(), 12u);
    // Each band's level over the frames that kept it.
    std::vector<double> kept_rms(8, 0.0);
    for (int b = 0; b < 8; ++b) {
        double sum = 0.0;
        std::size_t count = 0;
        for (std::size_t n = 0; n < x.size(); ++n)
            if ((r.selection[n / 1600] >> b) & 1u) sum += r.band_signals[b][n] * r.band_signals[b][n], ++count;
        kept_rms[b] = std::sqrt(sum / static_cast<double>(std::max<std::size_t>(count, 1)));
    }
    for (int seg = 0; seg < 12; ++seg) {
        std::uint64_t expected = 0;
        for (int b = 0; b < 8; ++b)
            if (ranks[seg][b] >= 5) expected |= std::uint64_t{1} << b;
        EXPECT_EQ(r.selection[seg], expected) << "frame " << seg;
        // The bands left out are silent in the middle of the frame.
        for (int b = 0; b < 8; ++b) {
            const auto mid = static_cast<std::size_t>((seg + 0.5) * 1600);
            std::vector<double> part(r.band_signals[b].begin() + mid - 200, r.band_signals[b].begin() + mid + 200);
            if (!((expected >> b) & 1u)) {
                EXPECT_LT(rms(part), 1e-2 * kept_rms[b]) << "frame " << seg << ", band " << b;
            }
        }
    }
    EXPECT_EQ(selection_csv({0b1011, 0b10000000}, 10), "frame,start_s,bands\n0,0.000000,0 1 3\n1,0.100000,7\n");
}

TEST(CiSimulation, SelectChannelsBreaksTiesToTheLowerBand) {
    const std::vector<std::vector<double>> analysis{{1, 1}, {2, 0}, {1, 1}, {0, 0}};
    // One frame per sample: energies (1, 4, 1, 0) then (1, 0, 1, 0).
    const ChannelSelection sel = select_channels(analysis, 2, 1.0, 1.0);
    ASSERT_EQ(sel.size(), 2u);
    EXPECT_EQ(sel[0], 0b0011u);
    EXPECT_EQ(sel[1], 0b0101u);
}

std::string problems_of(const VocoderSettings& s, double rate = 16000) {
    try {
        validate_settings(s, rate, "study.toml");
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(CiSimulation, ImpossibleSettingsAreRefusedByName) {
    VocoderSettings s;
    s.bands = 8;
    s.n_of_m = 12;
    EXPECT_NE(problems_of(s).find("vocoder.n_of_m: expected 0 (every channel) or at most the 8 bands, got 12"),
              std::string::npos)
        << problems_of(s);
    s = {};
    s.current_spread = CurrentSpread::DbPerOctave;
    s.spread_slope_db = -3;
    EXPECT_NE(problems_of(s).find("vocoder.spread_slope_db: expected a decay in (0, 1000]"), std::string::npos);
    s = {};
    s.carrier = CarrierType::Pshc;
    EXPECT_NE(problems_of(s).find("vocoder.carrier: the pulse-spreading harmonic complex (pshc"), std::string::npos);
    s = {};
    s.carrier = CarrierType::PulseTrain;
    s.bands = 16;
    s.pulse_rate_hz = 1000;
    s.pulse_width_us = 100;  // 16 × 100 µs > 1 ms
    EXPECT_NE(problems_of(s).find("expected interleaved pulses that do not overlap"), std::string::npos);
    s = {};
    s.carrier = CarrierType::PulseTrain;
    s.pulse_rate_hz = 1000;  // band 0 (100–531 Hz) holds no harmonic of 1000 Hz
    EXPECT_NE(problems_of(s).find("vocoder.pulse_rate_hz: expected every carrier band to hold a harmonic"),
              std::string::npos);
    s = {};
    s.insertion_shift_mm = 8;  // 5000 Hz moves above 8 kHz
    EXPECT_NE(problems_of(s).find("vocoder.insertion_shift_mm: expected carrier bands below the Nyquist"),
              std::string::npos);
    EXPECT_EQ(problems_of(s, 44100), "");
}

TEST(CiSimulation, EveryEntryPointGivesTheSameOutput) {
    VocoderSettings s;
    s.bands = 6;
    s.carrier = CarrierType::PoissonPulses;
    s.current_spread = CurrentSpread::DbPerOctave;
    s.n_of_m = 4;
    s.insertion_shift_mm = 2;
    Audio a;
    a.sample_rate_hz = 22050;
    const auto x = testing::speech_like(22050, 1.0);
    a.samples.assign(x.begin(), x.end());
    const VocoderResult fast = vocode(a, s);
    const VocoderResult plain = vocode_reference(a, s);
    EXPECT_EQ(fast.audio.samples, plain.audio.samples);
    EXPECT_EQ(fast.selection, plain.selection);
    EXPECT_FALSE(fast.selection.empty());
    AudioBufferSource source(a);
    Audio streamed;
    streamed.sample_rate_hz = a.sample_rate_hz;
    AudioBufferSink sink(streamed);
    const VocoderReport report = vocode_stream(source, sink, s);
    EXPECT_EQ(streamed.samples, plain.audio.samples);
    EXPECT_EQ(report.selection, plain.selection);
    const ChannelResult channel = vocode_channel(x, 22050, s);
    EXPECT_EQ(channel.selection, plain.selection);
}

TEST(CiSimulation, MethodsTextNamesEveryStage) {
    VocoderSettings s;
    s.bands = 8;
    s.carrier = CarrierType::PulseTrain;
    s.current_spread = CurrentSpread::DbPerMm;
    s.spread_slope_db = 2;
    s.insertion_shift_mm = 4;
    s.n_of_m = 4;
    s.synthesis_filter_order = 6;
    const std::string text = describe(s, 44100);
    for (const char* part : {"cochlear-implant simulation", "Carrier bands (Hz):", "4 mm basal", "mismatch",
                             "Synthesis filters:", "6th-order", "36 dB/octave", "2 dB per mm", "Channel selection:",
                             "4-of-8", "100 pulses/s", "interleaved", "first onsets 0.000, 1.250", "100 µs"})
        EXPECT_NE(text.find(part), std::string::npos) << part << "\n" << text;
    // The plain vocoder's text has none of it.
    EXPECT_EQ(describe(VocoderSettings{}, 44100).find("Carrier bands"), std::string::npos);
}

}  // namespace
}  // namespace avsi::vocoder
