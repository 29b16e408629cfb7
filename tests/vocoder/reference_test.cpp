// The fast path held to the reference path (avsi/vocoder/reference.h: the
// vocoder as its equations, one band at a time on one thread). Tolerance:
// none. The fast path is built to run the same IEEE operations in the same
// order as the reference (vocoder/src/reference.cpp names the three choices
// that fix the rounding; the library is compiled without FMA contraction),
// so every output sample and every reported level must have the same bits.
// Compared: vocode() (one thread, the whole signal stored), vocode_stream on
// two threads with blocks of several 4096-frame pieces and stores that end
// inside the signal (so the passes compute band outputs again, and the
// front and back, or the chunks of bands, run on two threads), and
// vocode_channel with its band signals, over carriers (noise, sine,
// low-noise), envelopes (half- and full-wave rectified, Hilbert), band
// counts from 1 to 16, the carrier filtered before and after modulation,
// zero phase, filter orders the fused loop does not take, level matching
// off, the anti-clipping scale, masking noise added before and after
// vocoding, and a seeded sweep of random settings.
#include "avsi/vocoder/reference.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "avsi/core/audio_stream.h"
#include "avsi/core/rng.h"
#include "avsi/vocoder/batch.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/vocoder.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

using testing::speech_like;

// `channels` channels of speech-like sound (a seed each, gains 1, 1.3, …)
// at `rate`, scaled by `gain`.
Audio input(int channels, int rate, double duration_s, double gain = 1.0) {
    Audio a;
    a.sample_rate_hz = rate;
    a.channels = channels;
    std::vector<std::vector<double>> x;
    for (int c = 0; c < channels; ++c) x.push_back(speech_like(rate, duration_s, 5 + c));
    a.samples.resize(x[0].size() * channels);
    for (std::size_t n = 0; n < x[0].size(); ++n)
        for (int c = 0; c < channels; ++c)
            a.samples[n * channels + c] = static_cast<float>(gain * (1.0 + 0.3 * c) * x[c][n]);
    return a;
}

// The index of the first sample whose bits differ, or the length of the
// shorter (the longer's extra samples count as differing).
template <typename T>
std::size_t first_difference(const std::vector<T>& a, const std::vector<T>& b) {
    const std::size_t n = std::min(a.size(), b.size());
    for (std::size_t i = 0; i < n; ++i)
        if (std::memcmp(&a[i], &b[i], sizeof(T)) != 0) return i;
    return a.size() == b.size() ? SIZE_MAX : n;
}

// A value with every digit it needs to be told apart.
template <typename T>
std::string exact(T value) {
    std::ostringstream out;
    out << std::setprecision(std::numeric_limits<T>::max_digits10) << value;
    return out.str();
}

template <typename T>
void expect_same_bits(const std::vector<T>& fast, const std::vector<T>& reference, const std::string& what) {
    const std::size_t at = first_difference(fast, reference);
    if (at == SIZE_MAX) return;
    if (at < std::min(fast.size(), reference.size()))
        ADD_FAILURE() << what << ": sample " << at << " is " << exact(fast[at]) << " on the fast path, "
                      << exact(reference[at]) << " on the reference";
    else
        ADD_FAILURE() << what << ": " << fast.size() << " samples on the fast path, " << reference.size()
                      << " on the reference";
}

void expect_same_bits(double fast, double reference, const std::string& what) {
    EXPECT_EQ(std::bit_cast<std::uint64_t>(fast), std::bit_cast<std::uint64_t>(reference))
        << what << ": " << exact(fast) << " on the fast path, " << exact(reference) << " on the reference";
}

void expect_same_bands(const std::vector<BandInfo>& fast, const std::vector<BandInfo>& reference) {
    ASSERT_EQ(fast.size(), reference.size());
    for (std::size_t b = 0; b < fast.size(); ++b) {
        const std::string band = "band " + std::to_string(b);
        expect_same_bits(fast[b].low_hz, reference[b].low_hz, band + " low_hz");
        expect_same_bits(fast[b].high_hz, reference[b].high_hz, band + " high_hz");
        expect_same_bits(fast[b].centre_hz, reference[b].centre_hz, band + " centre_hz");
        expect_same_bits(fast[b].analysis_rms, reference[b].analysis_rms, band + " analysis_rms");
        expect_same_bits(fast[b].output_rms, reference[b].output_rms, band + " output_rms");
    }
}

void expect_same_result(const VocoderResult& fast, const VocoderResult& reference) {
    expect_same_bits(fast.audio.samples, reference.audio.samples, "samples");
    expect_same_bands(fast.bands, reference.bands);
    expect_same_bits(fast.output_gain_db, reference.output_gain_db, "output_gain_db");
    expect_same_bits(fast.peak_before_limit, reference.peak_before_limit, "peak_before_limit");
    expect_same_bits(fast.limit_gain_db, reference.limit_gain_db, "limit_gain_db");
}

// vocode_stream with `limits` into memory.
VocoderResult vocode_streaming(const Audio& in, const VocoderSettings& s, const detail::StreamLimits& limits) {
    AudioBufferSource source(in);
    VocoderResult result;
    result.audio.sample_rate_hz = in.sample_rate_hz;
    result.audio.channels = in.channels;
    AudioBufferSink sink(result.audio);
    const VocoderReport report = detail::vocode_stream(source, sink, s, limits);
    result.bands = report.bands;
    result.output_gain_db = report.output_gain_db;
    result.peak_before_limit = report.peak_before_limit;
    result.limit_gain_db = report.limit_gain_db;
    return result;
}

// Every fast path against the reference on `in`.
void expect_fast_paths_match_the_reference(const Audio& in, const VocoderSettings& s) {
    const VocoderResult reference = vocode_reference(in, s);
    {
        SCOPED_TRACE("vocode");
        expect_same_result(vocode(in, s), reference);
    }
    // Stores of 6000 frames (pass 2's sums then fit for more, not all) and
    // of none, in blocks of two and of one and a half 4096-frame pieces.
    const std::size_t per_frame = static_cast<std::size_t>(s.bands * in.channels) * sizeof(float);
    for (const detail::StreamLimits limits : {detail::StreamLimits{8192, 6000 * per_frame, 2},
                                              detail::StreamLimits{6144, 0, 2}}) {
        SCOPED_TRACE(::testing::Message() << "vocode_stream, block " << limits.block_frames << ", store "
                                          << limits.store_bytes << ", 2 threads");
        expect_same_result(vocode_streaming(in, s, limits), reference);
    }
    SCOPED_TRACE("vocode_channel, channel 1, band signals");
    const std::vector<float> samples = in.channel(0);
    const std::vector<double> x(samples.begin(), samples.end());
    const ChannelResult fast = vocode_channel(x, in.sample_rate_hz, s, 1, true);
    const ChannelResult plain = vocode_channel_reference(x, in.sample_rate_hz, s, 1, true);
    expect_same_bits(fast.samples, plain.samples, "samples");
    expect_same_bands(fast.bands, plain.bands);
    expect_same_bits(fast.output_gain_db, plain.output_gain_db, "output_gain_db");
    ASSERT_EQ(fast.band_signals.size(), plain.band_signals.size());
    for (std::size_t b = 0; b < fast.band_signals.size(); ++b)
        expect_same_bits(fast.band_signals[b], plain.band_signals[b], "band signal " + std::to_string(b));
}

struct Case {
    const char* name;
    VocoderSettings settings;
    int channels = 1;
    double gain = 1.0;
};

std::vector<Case> cases() {
    std::vector<Case> out;
    auto add = [&](const char* name, auto change, int channels = 1, double gain = 1.0) {
        VocoderSettings s;
        change(s);
        out.push_back(Case{name, s, channels, gain});
    };
    // Noise carriers, rectified envelopes, 1 to 16 bands (one chunk of 4
    // lanes, padded or not, and two or more).
    add("default: 3 bands, noise, half-wave", [](VocoderSettings&) {});
    add("1 band", [](VocoderSettings& s) { s.bands = 1; });
    add("4 bands", [](VocoderSettings& s) { s.bands = 4; });
    add("5 bands, log spacing", [](VocoderSettings& s) { s.bands = 5; s.spacing = BandSpacing::Log; });
    add("8 bands, stereo, seed 7", [](VocoderSettings& s) { s.bands = 8; s.seed = 7; }, 2);
    add("16 bands, envelope order 2", [](VocoderSettings& s) {
        s.bands = 16; s.envelope_filter_order = 2; s.low_hz = 80; s.high_hz = 7000; });
    add("full-wave", [](VocoderSettings& s) { s.envelope = EnvelopeMethod::FullWaveRectify; });
    add("6 bands, linear, full-wave", [](VocoderSettings& s) {
        s.bands = 6; s.spacing = BandSpacing::Linear; s.envelope = EnvelopeMethod::FullWaveRectify; });
    // Sine and low-noise carriers.
    add("sine", [](VocoderSettings& s) { s.carrier = CarrierType::Sine; });
    add("sine, 8 bands, full-wave", [](VocoderSettings& s) {
        s.carrier = CarrierType::Sine; s.bands = 8; s.envelope = EnvelopeMethod::FullWaveRectify; });
    add("low-noise", [](VocoderSettings& s) { s.carrier = CarrierType::LowNoise; s.low_noise_iterations = 3; });
    add("low-noise, 5 bands, no iterations", [](VocoderSettings& s) {
        s.carrier = CarrierType::LowNoise; s.low_noise_iterations = 0; s.bands = 5; });
    // Hilbert envelopes.
    add("Hilbert", [](VocoderSettings& s) { s.envelope = EnvelopeMethod::Hilbert; });
    add("Hilbert, 8 bands, sine", [](VocoderSettings& s) {
        s.envelope = EnvelopeMethod::Hilbert; s.bands = 8; s.carrier = CarrierType::Sine; });
    add("Hilbert, low-noise", [](VocoderSettings& s) {
        s.envelope = EnvelopeMethod::Hilbert; s.carrier = CarrierType::LowNoise; s.low_noise_iterations = 2; });
    // The carrier filtered before modulation, after it, both, neither.
    add("prefilter and refilter", [](VocoderSettings& s) { s.prefilter_carrier = true; });
    add("prefilter, no refilter", [](VocoderSettings& s) { s.prefilter_carrier = true; s.refilter_carrier = false; });
    add("no refilter, 6 bands", [](VocoderSettings& s) { s.refilter_carrier = false; s.bands = 6; });
    add("sine, 12 bands, prefilter", [](VocoderSettings& s) {
        s.carrier = CarrierType::Sine; s.bands = 12; s.prefilter_carrier = true; s.high_hz = 7000; });
    // Zero phase; orders the fused loop does not take (the plain way).
    add("zero phase", [](VocoderSettings& s) { s.zero_phase = true; });
    add("zero phase, sine, 4 bands", [](VocoderSettings& s) {
        s.zero_phase = true; s.carrier = CarrierType::Sine; s.bands = 4; });
    add("filter order 6", [](VocoderSettings& s) { s.filter_order = 6; });
    add("filter order 2, 7 bands", [](VocoderSettings& s) { s.filter_order = 2; s.bands = 7; });
    add("envelope order 3", [](VocoderSettings& s) { s.envelope_filter_order = 3; });
    add("explicit edges", [](VocoderSettings& s) {
        s.bands = 2; s.spacing = BandSpacing::Explicit; s.edges_hz = {100.0, 900.0, 5000.0}; });
    // Level matching off; the anti-clipping scale.
    add("no level matching", [](VocoderSettings& s) { s.match_band_rms = false; s.match_output_rms = false; });
    add("band levels only", [](VocoderSettings& s) { s.match_output_rms = false; });
    add("loud, stereo: scaled down", [](VocoderSettings&) {}, 2, 9.0);
    return out;
}

TEST(VocoderReference, FastPathGivesTheReferenceOutputBitForBit) {
    for (const Case& c : cases()) {
        SCOPED_TRACE(c.name);
        expect_fast_paths_match_the_reference(input(c.channels, 16000, 1.3, c.gain), c.settings);
    }
}

// The loud case above compares the anti-clipping scale: it does scale.
TEST(VocoderReference, LoudCaseReachesTheAntiClippingScale) {
    const Audio in = input(2, 16000, 1.3, 9.0);
    const VocoderResult plain = vocode_reference(in, VocoderSettings{});
    EXPECT_GT(plain.peak_before_limit, 1.0);
    EXPECT_LT(plain.limit_gain_db, 0.0);
}

TEST(VocoderReference, EmptyAndSilentInputMatch) {
    Audio empty;
    empty.sample_rate_hz = 16000;
    expect_same_result(vocode(empty, VocoderSettings{}), vocode_reference(empty, VocoderSettings{}));
    Audio silence = empty;
    silence.samples.assign(9000, 0.0f);
    expect_fast_paths_match_the_reference(silence, VocoderSettings{});
}

// Masking noise added before vocoding and after it (process_audio, which
// vocodes with vocode()): the same as the reference vocoder in its place.
TEST(VocoderReference, MaskingNoiseBeforeOrAfterVocodingMatches) {
    const Audio speech = input(1, 16000, 1.3);
    Rng rng(3);
    std::vector<double> noise(15000);
    for (double& v : noise) v = 0.1 * rng.normal();
    for (NoiseStage stage : {NoiseStage::BeforeVocoding, NoiseStage::AfterVocoding}) {
        SCOPED_TRACE(stage == NoiseStage::BeforeVocoding ? "noise before vocoding" : "noise after vocoding");
        ProcessSettings p;
        p.vocoder.bands = 4;
        p.noise.kind = NoiseKind::File;
        p.noise.stage = stage;
        p.noise.mix.snr_db = 3.0;
        const std::uint64_t seed = 11;
        const Audio fast = process_audio(speech, p, nullptr, &noise, seed);
        MixSettings mix = p.noise.mix;
        mix.seed = seed;
        const Audio plain = stage == NoiseStage::BeforeVocoding
                                ? vocode_reference(mix_at_snr(speech, noise, mix).audio, p.vocoder).audio
                                : mix_at_snr(vocode_reference(speech, p.vocoder).audio, noise, mix).audio;
        expect_same_bits(fast.samples, plain.samples, "samples");
    }
}

// Random settings, each valid for the rate: the seed in the trace.
TEST(VocoderReference, RandomSettingsGiveTheReferenceOutputBitForBit) {
    for (std::uint64_t seed = 1; seed <= 16; ++seed) {
        Rng rng(seed);
        VocoderSettings s;
        const int rate = rng.uniform() < 0.5 ? 16000 : 22050;
        s.bands = 1 + static_cast<int>(rng.uniform_int(12));
        s.low_hz = rng.uniform(60.0, 300.0);
        s.high_hz = rng.uniform(3000.0, 0.45 * rate);
        s.spacing = std::vector{BandSpacing::Greenwood, BandSpacing::Log, BandSpacing::Linear}[rng.uniform_int(3)];
        s.filter_order = 1 + static_cast<int>(rng.uniform_int(6));
        s.envelope = std::vector{EnvelopeMethod::HalfWaveRectify, EnvelopeMethod::FullWaveRectify,
                                 EnvelopeMethod::Hilbert}[rng.uniform_int(3)];
        s.envelope_cutoff_hz = rng.uniform(30.0, 400.0);
        s.envelope_filter_order = 1 + static_cast<int>(rng.uniform_int(6));
        s.carrier = std::vector{CarrierType::Noise, CarrierType::Sine, CarrierType::LowNoise}[rng.uniform_int(3)];
        s.low_noise_iterations = static_cast<int>(rng.uniform_int(4));
        s.prefilter_carrier = rng.uniform() < 0.3;
        s.refilter_carrier = rng.uniform() < 0.8;
        s.zero_phase = rng.uniform() < 0.2;
        s.match_band_rms = rng.uniform() < 0.8;
        s.match_output_rms = rng.uniform() < 0.8;
        s.seed = rng.next_u64();
        const int channels = rng.uniform() < 0.25 ? 2 : 1;
        SCOPED_TRACE(::testing::Message() << "seed " << seed << ": " << s.bands << " bands, " << to_string(s.carrier)
                                          << ", " << to_string(s.envelope) << ", " << channels << " channels at "
                                          << rate << " Hz");
        expect_fast_paths_match_the_reference(input(channels, rate, 0.8), s);
    }
}

}  // namespace
}  // namespace avsi::vocoder
