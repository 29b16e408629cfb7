// Bit-exact regression of the vocoder and the noise mix: SHA-256 of the
// float output for a set of settings, recorded from the implementation
// before the streaming rewrite (issue 21; commit "tests/vocoder: golden
// hashes"). Any change to a sample changes a hash. The same outputs through
// the streaming path with small blocks and a small store (so the passes that
// recompute the pipeline run) must give the same hashes.
//
// AVSI_UPDATE_GOLDEN=1 prints the hashes instead of comparing (review the
// diff: a changed hash means changed stimuli).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "avsi/core/files.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/resample.h"
#include "avsi/vocoder/stoi.h"
#include "avsi/vocoder/vocoder.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

using testing::speech_like;

std::string hash_of(const std::vector<float>& samples) {
    return sha256_hex(std::string_view(reinterpret_cast<const char*>(samples.data()), samples.size() * sizeof(float)));
}

// 1.3 s of speech-like sound at 16 kHz; `channels` copies with different
// gains (and a seed each) interleaved; `gain` scales the whole.
Audio input(int channels, double gain = 1.0, double duration_s = 1.3) {
    Audio a;
    a.sample_rate_hz = 16000;
    a.channels = channels;
    std::vector<std::vector<double>> x;
    for (int c = 0; c < channels; ++c) x.push_back(speech_like(16000, duration_s, 5 + c));
    a.samples.resize(x[0].size() * channels);
    for (std::size_t n = 0; n < x[0].size(); ++n)
        for (int c = 0; c < channels; ++c) a.samples[n * channels + c] = static_cast<float>(gain * (1.0 + 0.3 * c) * x[c][n]);
    return a;
}

struct Case {
    const char* name;
    VocoderSettings settings;
    int channels = 1;
    double gain = 1.0;
    const char* expected;
};

std::vector<Case> cases() {
    std::vector<Case> out;
    auto add = [&](const char* name, auto change, int channels, double gain, const char* expected) {
        VocoderSettings s;
        change(s);
        out.push_back(Case{name, s, channels, gain, expected});
    };
    add("default", [](VocoderSettings&) {}, 1, 1.0, "1159980df5d66ec3e65ffbd1d8c3c174b21e060cc058c995fac6e8c75d4835a8");
    add("stereo-8-bands-seed-7", [](VocoderSettings& s) { s.bands = 8; s.seed = 7; }, 2, 1.0, "a99c246afbe2e1963d750c2a6cd45c203f46b52ee8bbf6cf7e875b77a4c3bb24");
    add("5-bands-log-order-6", [](VocoderSettings& s) { s.bands = 5; s.spacing = BandSpacing::Log; s.filter_order = 6; }, 1, 1.0, "4416db48e9191017e87b3c9defe16be63dc3521899d912a7d74a457d6e013395");
    add("sine-full-wave", [](VocoderSettings& s) { s.carrier = CarrierType::Sine; s.envelope = EnvelopeMethod::FullWaveRectify; }, 1, 1.0, "0ca5a7b0f537b237fa9cf24b3fa29968a1fe7565e9856160f225478bdd29d28d");
    add("prefilter-no-refilter", [](VocoderSettings& s) { s.prefilter_carrier = true; s.refilter_carrier = false; }, 1, 1.0, "9c785db1a54e11decbe2111cfbe9597c6f5ab93424d759c0a62c14a1f44ef467");
    add("no-level-matching", [](VocoderSettings& s) { s.match_band_rms = false; s.match_output_rms = false; }, 1, 1.0, "844e41f61bd2d448eb5b0d87d91b11bb0efbedb310605cd7d0dc7671c6a0c71e");
    add("loud-limited", [](VocoderSettings&) {}, 2, 9.0, "7fa657d874a27b57fdebca0872d4045a6896ab53ddf3c76b0880becbf822ddac");
    add("zero-phase", [](VocoderSettings& s) { s.zero_phase = true; }, 1, 1.0, "3eef0962960df90b39c60b3255144038a06481869c9dd23b81d26a175bb771f8");
    add("hilbert", [](VocoderSettings& s) { s.envelope = EnvelopeMethod::Hilbert; }, 1, 1.0, "f8b743b126a4e6281191a167b47e86620fea6a594b03804aecf006e6323d5b51");
    add("low-noise", [](VocoderSettings& s) { s.carrier = CarrierType::LowNoise; s.low_noise_iterations = 3; }, 1, 1.0, "383c6d6323e90b7aae7b02a8520235b504359a9cbe664ff55ff6267230b56797");
    add("16-bands-envelope-order-2", [](VocoderSettings& s) { s.bands = 16; s.envelope_filter_order = 2; s.low_hz = 80; s.high_hz = 7000; }, 1, 1.0, "d8cc77033cbc1692de171c8215f525966751ed8999e58c9cbef7ceac12cb4d06");
    return out;
}

bool updating() { return std::getenv("AVSI_UPDATE_GOLDEN") != nullptr; }

TEST(VocoderGolden, OutputMatchesTheRecordedHashes) {
    for (const Case& c : cases()) {
        SCOPED_TRACE(c.name);
        const std::string hash = hash_of(vocode(input(c.channels, c.gain), c.settings).audio.samples);
        if (updating())
            std::printf("    {\"%s\", \"%s\"},\n", c.name, hash.c_str());
        else
            EXPECT_EQ(hash, c.expected);
    }
}

// The two-channel hashes were recorded again when dev gave every channel
// channel 0's noise carrier (dual-mono stays dual-mono; issue 20's --channels
// keep). What they pin is each channel vocoded on its own with channel 0's
// carrier (vocode_channel, whose mono output the other hashes pin), then the
// one anti-clipping scale of the whole output — checked here sample by sample.
TEST(VocoderGolden, EveryChannelIsVocodedWithChannel0sCarrier) {
    for (const Case& c : cases()) {
        if (c.channels < 2) continue;
        SCOPED_TRACE(c.name);
        const Audio in = input(c.channels, c.gain);
        const VocoderResult result = vocode(in, c.settings);
        std::vector<std::vector<double>> channels;
        double peak = 0.0;
        for (int ch = 0; ch < in.channels; ++ch) {
            const std::vector<float> samples = in.channel(ch);
            const std::vector<double> x(samples.begin(), samples.end());
            channels.push_back(vocode_channel(x, in.sample_rate_hz, c.settings, 0).samples);
            for (double v : channels.back()) peak = std::max(peak, std::abs(v));
        }
        const double scale = peak > 1.0 ? 0.999 / peak : 1.0;
        ASSERT_EQ(result.audio.samples.size(), channels[0].size() * in.channels);
        std::size_t differing = 0;
        for (std::size_t n = 0; n < channels[0].size(); ++n)
            for (int ch = 0; ch < in.channels; ++ch)
                differing += result.audio.samples[n * in.channels + ch] != static_cast<float>(channels[ch][n] * scale);
        EXPECT_EQ(differing, 0u);
        EXPECT_DOUBLE_EQ(result.peak_before_limit, peak);
    }
}

// The streaming path with short odd blocks and a store of nothing, of a
// few frames (its end inside a block), of most frames (the sums of pass 2
// then fit for all frames, or for some, in the same memory) and of
// everything, on one thread or two (blocks of several 4096-frame pieces):
// the passes that compute the band outputs again must give the same samples.
TEST(VocoderGolden, StreamingWithAnyBlockAndStoreGivesTheRecordedHashes) {
    const std::vector<detail::StreamLimits> limits = {
        {333, 0, 2},         {1000, 12345, 2}, {700, 200000, 2},   {4096, std::size_t{1} << 30, 2},
        {1, 64, 2},          {20000, 0, 2},    {9000, 100000, 2},  {32768, std::size_t{1} << 30, 2},
        {32768, 150000, 1}};
    for (const Case& c : cases()) {
        SCOPED_TRACE(c.name);
        const Audio in = input(c.channels, c.gain, c.settings.bands > 8 ? 0.4 : 1.3);
        const std::string expected = hash_of(vocode(in, c.settings).audio.samples);
        if (c.settings.bands <= 8) {
            EXPECT_EQ(expected, c.expected);
        }
        for (const detail::StreamLimits& l : limits) {
            if (l.block_frames == 1 && c.settings.bands > 3) continue;  // slow and adds nothing
            SCOPED_TRACE(::testing::Message() << "block " << l.block_frames << ", store " << l.store_bytes
                                               << ", threads " << l.threads);
            AudioBufferSource source(in);
            Audio out;
            out.sample_rate_hz = in.sample_rate_hz;
            out.channels = in.channels;
            AudioBufferSink sink(out);
            const VocoderReport report = detail::vocode_stream(source, sink, c.settings, l);
            EXPECT_EQ(hash_of(out.samples), expected);
            EXPECT_EQ(report.bands.size(), static_cast<std::size_t>(c.settings.bands));
        }
    }
}

// A store of several huge pages (2 MiB), which the worker faults in ahead
// while it waits and gives back piece by piece in pass 3 (the stores above
// are smaller, and malloc'd), with a part past it that pass 2 makes again
// and adds up on the worker: the same samples as one thread with the whole
// signal stored. Three bands (one chunk: fronts and backs on two threads)
// and eight in stereo (two chunks, one per thread; pass 3 computes again
// what its sums did not fit).
TEST(VocoderGolden, StoreOfSeveralHugePagesOnTwoThreadsGivesTheSameSamples) {
    VocoderSettings three, eight;
    eight.bands = 8;
    for (auto [settings, channels] : {std::pair{three, 1}, std::pair{eight, 2}}) {
        SCOPED_TRACE(::testing::Message() << settings.bands << " bands, " << channels << " channels");
        const Audio in = input(channels, 1.0, 40.0);
        const std::string expected = hash_of(vocode(in, settings).audio.samples);
        for (unsigned threads : {1u, 2u}) {
            SCOPED_TRACE(::testing::Message() << threads << " threads");
            AudioBufferSource source(in);
            Audio out;
            out.sample_rate_hz = in.sample_rate_hz;
            out.channels = in.channels;
            AudioBufferSink sink(out);
            detail::vocode_stream(source, sink, settings, detail::StreamLimits{32768, std::size_t{5} << 20, threads});
            EXPECT_EQ(hash_of(out.samples), expected);
        }
    }
}

// A source that announces `announced` frames (the audio's, then silence)
// and gives them all until its `short_from`-th seek (1: pass 1), after
// which it ends at frame `ends_at`.
class EndsEarly : public AudioSource {
public:
    EndsEarly(const Audio& audio, std::size_t announced, int short_from, std::size_t ends_at)
        : m_audio(audio), m_announced(announced), m_short_from(short_from), m_ends_at(ends_at) {}
    int sample_rate_hz() const override { return m_audio.sample_rate_hz; }
    int channels() const override { return m_audio.channels; }
    std::size_t frames() const override { return m_announced; }
    std::size_t read(float* out, std::size_t frames) override {
        const std::size_t end = m_seeks >= m_short_from ? m_ends_at : m_announced;
        const std::size_t n = std::min(frames, end - std::min(end, m_position));
        const std::size_t nc = static_cast<std::size_t>(m_audio.channels);
        for (std::size_t i = 0; i < n * nc; ++i) {
            const std::size_t at = m_position * nc + i;
            out[i] = at < m_audio.samples.size() ? m_audio.samples[at] : 0.0f;
        }
        m_position += n;
        return n;
    }
    void seek(std::size_t frame) override {
        ++m_seeks;
        m_position = frame;
    }

private:
    const Audio& m_audio;
    std::size_t m_announced;
    int m_short_from;
    std::size_t m_ends_at;
    int m_seeks = 0;
    std::size_t m_position = 0;
};

// An input that ends before the length it announced, in the middle of a
// block of several pieces (the worker then waits for pieces that do not
// come), in pass 1 or in a replay that reads past the store, on one thread
// or two, with one chunk of bands or two: a clear error, no hang.
TEST(VocoderGolden, AnInputThatEndsEarlyIsAnErrorOnEveryPath) {
    for (int channels : {1, 2}) {
        for (int bands : {3, 8}) {
            const Audio in = input(channels, 1.0, 12.0);  // 192000 frames
            VocoderSettings s;
            s.bands = bands;
            for (int short_from : {1, 2, 3}) {
                for (unsigned threads : {1u, 2u}) {
                    SCOPED_TRACE(::testing::Message() << channels << " channels, " << bands << " bands, short from seek "
                                                      << short_from << ", " << threads << " threads");
                    // Stored: the first 20000 frames (so pass 2 keeps the sums of
                    // 10000 × bands < 151000 frames, and pass 3 reads the input
                    // too); the input ends at 151000, in a block's fifth piece.
                    const detail::StreamLimits limits{32768, 20000 * static_cast<std::size_t>(bands * channels) * 4,
                                                      threads};
                    EndsEarly source(in, 192000, short_from, 151000);
                    Audio out;
                    out.sample_rate_hz = in.sample_rate_hz;
                    out.channels = in.channels;
                    AudioBufferSink sink(out);
                    try {
                        detail::vocode_stream(source, sink, s, limits);
                        ADD_FAILURE() << "no error";
                    } catch (const InputError& e) {
                        EXPECT_NE(std::string(e.what()).find("expected 192000 frames, the input ended after fewer"),
                                  std::string::npos)
                            << e.what();
                    }
                    // Nothing of the output was written before the input was read twice.
                    if (short_from < 3) {
                        EXPECT_EQ(out.samples.size(), 0u);
                    }
                }
            }
        }
    }
}

// STOI's resampling in pieces (any sizes) gives resample()'s samples.
TEST(VocoderGolden, StreamResamplerMatchesTheOneShotResampler) {
    for (double rate : {22050.0, 44100.0, 16000.0, 8000.0, 10000.0}) {
        SCOPED_TRACE(rate);
        const std::vector<double> x = speech_like(rate, 0.9, 3);
        const std::vector<double> whole = resample(x, rate, 10000.0);
        for (std::size_t piece : {1u, 1000u, 8192u, 100000u}) {
            StreamResampler r(rate, 10000.0, x.size());
            std::vector<double> out;
            for (std::size_t i = 0; i < x.size(); i += piece) r.feed(x.data() + i, std::min(piece, x.size() - i), out);
            EXPECT_EQ(r.output_frames(), whole.size());
            EXPECT_EQ(out, whole) << "pieces of " << piece;
        }
    }
}

std::string hex(double v) {
    char text[64];
    std::snprintf(text, sizeof text, "%a", v);
    return text;
}

// Speech with a pause: `channels` channels, 1 s of speech, 0.5 s of
// silence, 0.6 s of softer speech.
Audio with_pause(int channels) {
    Audio a = input(channels, 1.0, 1.0);
    a.samples.resize(a.samples.size() + 8000 * channels, 0.0f);
    const Audio tail = input(channels, 0.5, 0.6);
    a.samples.insert(a.samples.end(), tail.samples.begin(), tail.samples.end());
    return a;
}

// The mix (speech-shaped noise, and a noise recording longer and shorter
// than the speech), the speech level and STOI/ESTOI: hashes of the samples
// and the exact values.
TEST(VocoderGolden, MixLevelAndStoiMatchTheRecordedValues) {
    const Audio speech = with_pause(2);
    const LongTermSpectrum ltas = long_term_spectrum({speech});
    const std::vector<double> shaped = speech_shaped_noise(ltas, speech.frames(), speech.sample_rate_hz, 11);
    const std::vector<double> long_noise = speech_shaped_noise(ltas, speech.frames() * 3 + 17, speech.sample_rate_hz, 12);
    const std::vector<double> short_noise(shaped.begin(), shaped.begin() + 5000);
    const std::vector<float> mono_f = speech.mono();
    const std::vector<double> mono(mono_f.begin(), mono_f.end());
    const Audio clean = with_pause(1);
    const Audio vocoded = vocode(clean, VocoderSettings{}).audio;
    std::vector<std::pair<std::string, std::string>> values;
    for (SnrReference reference : {SnrReference::WholeSignal, SnrReference::ActiveFrames}) {
        const std::string r = to_string(reference);
        MixSettings m{.snr_db = -3.0, .reference = reference, .seed = 4};
        values.emplace_back("mix-shaped-" + r, hash_of(mix_at_snr(speech, shaped, m).audio.samples));
        values.emplace_back("mix-long-" + r, hash_of(mix_at_snr(speech, long_noise, m).audio.samples));
        values.emplace_back("mix-short-" + r, hash_of(mix_at_snr(speech, short_noise, m).audio.samples));
        m.snr_db = -25.0;  // loud noise: the mixture is scaled down
        values.emplace_back("mix-loud-" + r, hash_of(mix_at_snr(speech, shaped, m).audio.samples));
        values.emplace_back("level-" + r, hex(speech_level_rms(mono, speech.sample_rate_hz, reference)));
    }
    values.emplace_back("stoi", hex(stoi(clean, vocoded)));
    values.emplace_back("estoi", hex(stoi(clean, vocoded, {.extended = true})));
    const std::vector<std::pair<std::string, std::string>> expected = {
        {"mix-shaped-whole", "2bac8ef4616670f37444b31d1179c9780115024f057beee0117a169d40421d68"},
        {"mix-long-whole", "2e5133cfaded886c37f07c6999d742941ecc949fe3eed6d8a69a821b09de0450"},
        {"mix-short-whole", "bf556c78dbdd63e02a571cf1b9357f66586c3ed85bec8b5c21d23ec608c8b5e5"},
        {"mix-loud-whole", "8c4522634a71e64428f4c67902f3026ffc0bf0b4c7af9157c96ab56db02bef7d"},
        {"level-whole", "0x1.e6f0f459b03a3p-7"},
        {"mix-shaped-active", "465909792898577a63425bfa3f1ee9c8352cb8c95da21be7cb0b2466740f8e36"},
        {"mix-long-active", "c34c3dc0523fdb353d62b2501af15c97cc82232e97b4c0fd2adbdc04b0895253"},
        {"mix-short-active", "be41f9f105f63230f9555b12b7e442ae0ab8d3a75844d28718719882e40da58b"},
        {"mix-loud-active", "5c2d366fb4cb3979507a544627238d3ab5ebc02438210590f806c4b29429f3c2"},
        {"level-active", "0x1.16ee3dc17d3e5p-6"},
        {"stoi", "0x1.5cbba6023c57bp-1"},
        {"estoi", "0x1.c5bae72bf86d4p-4"},
    };
    if (updating()) {
        for (const auto& [name, value] : values) std::printf("        {\"%s\", \"%s\"},\n", name.c_str(), value.c_str());
        return;
    }
    EXPECT_EQ(values, expected);
}

}  // namespace
}  // namespace avsi::vocoder
