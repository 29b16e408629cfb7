// The vocoder's fast path: vocode(), vocode_stream() and vocode_channel().
// The same output as the one-thread reference (reference.cpp, where the
// equations are) bit for bit; what it does differently, and why:
//   - the signal comes from a source in blocks and goes to a sink, so that
//     memory is bounded whatever its length. Level matching and the
//     anti-clipping scale need the whole signal's levels before the first
//     sample is written, so each channel runs in three passes
//     (channel_engine.h): measure; the level of the band sum; write;
//   - the band outputs of pass 1 are kept in a store of up to a budget
//     (StreamLimits::store_bytes) and computed again past it; pass 2 keeps
//     its sums in the same memory for pass 3;
//   - the bands run side by side in vector lanes, for the common settings in
//     one fused loop (fused_pipeline.h), and with StreamLimits::threads = 2
//     on two threads (channel_pipeline.h), pass 3 writing beside its sums.
// docs/performance.md ("The vocoder's fast path") has the measurements.
#include "avsi/vocoder/vocoder.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/log.h"
#include "avsi/core/memory.h"
#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/reference.h"
#include "channel_engine.h"
#include "channel_pipeline.h"
#include "pair_worker.h"

namespace avsi::vocoder {

namespace detail {

namespace {

double to_db(double ratio) { return 20.0 * std::log10(ratio); }

// The analysis filters, centre frequencies and band descriptions.
struct BandSetup {
    std::vector<Sos> filters;
    std::vector<double> centres;
    std::vector<BandInfo> bands;
};

BandSetup band_setup(const VocoderSettings& s, double rate) {
    const std::vector<double> edges = band_edges_hz(s);
    BandSetup setup;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
        setup.filters.push_back(butterworth_bandpass(s.filter_order, edges[b], edges[b + 1], rate));
        BandInfo info;
        info.low_hz = edges[b];
        info.high_hz = edges[b + 1];
        info.centre_hz = std::sqrt(edges[b] * edges[b + 1]);
        setup.centres.push_back(info.centre_hz);
        setup.bands.push_back(info);
    }
    return setup;
}

// Throws InputError unless the source has a channel and a positive rate.
void check_source(const AudioSource& input) {
    if (input.channels() < 1 || input.sample_rate_hz() <= 0)
        throw InputError(Diagnostic{"", 0, 0, "audio",
                                    fmt::format("expected at least one channel and a positive sample "
                                                "rate, got {} channels at {} Hz",
                                                input.channels(), input.sample_rate_hz())});
}

// *sq_sum += Σ sums², *top_abs = max(*top_abs, max |sums|), in frame order.
void add_energy_and_peak(const double* sums, std::size_t count, double* sq_sum, double* top_abs) {
    double sq = *sq_sum, top = *top_abs;
    for (std::size_t n = 0; n < count; ++n) {
        sq += sums[n] * sums[n];
        top = std::max(top, std::abs(sums[n]));
    }
    *sq_sum = sq;
    *top_abs = top;
}

// What pass 2 found: the gains of the output.
struct OutputLevels {
    std::vector<double> gain;      // per channel: sqrt(Σx² / Σs²), when applied
    std::vector<bool> apply_gain;  // per channel: match_output_rms, and the sum not silent
    double output_gain_db = 0.0;   // channel 0's gain
    double peak = 0.0;             // the largest |sample| before the anti-clipping scale
    double scale = 1.0;            // the anti-clipping scale
    double limit_gain_db = 0.0;    // the scale in dB (< 0 when the output is scaled down)
};

// The three passes over every channel of a source (channel_engine.h), with
// the buffers they share.
class StreamPasses {
public:
    StreamPasses(AudioSource& input, AudioSink& output, const VocoderSettings& s, const StreamLimits& limits,
                 const BandSetup& setup);

    // Pass 1: steps 1–4 and what they measure; channel 0's bands.
    std::vector<BandInfo> measure(const std::vector<BandInfo>& bands);
    // Pass 2: the band sum's energy and peak per channel, then the gains.
    OutputLevels sum_levels();
    // Pass 3: the output, written to the sink.
    void write(const OutputLevels& levels);

private:
    // Reads the next `count` frames of the input into the block from `offset`.
    void read_frames(std::size_t offset, std::size_t count);
    // Frames [offset, offset + count) of channel c of what was read, into x.
    void deinterleave(std::size_t offset, std::size_t count, std::size_t c);
    // A replay (pass 2 or 3) of every channel (see replay in the .cpp).
    template <typename Consume, typename ThenOf>
    void replay(Consume&& consume, bool keep, ThenOf&& then_of);
    // The gains from pass 2's measurements, and the anti-clipping scale.
    OutputLevels output_levels() const;
    // Pass 3: channel c of the block's sums into the output block; after the
    // last channel, the block to the sink.
    void output_block(const OutputLevels& levels, std::size_t c, std::size_t first, std::size_t count);
    void write_block(std::size_t first, std::size_t count);

    AudioSource& m_input;
    AudioSink& m_output;
    const VocoderSettings& m_settings;
    const std::size_t m_nc;
    const std::size_t m_frames;
    const std::size_t m_block;
    std::vector<std::unique_ptr<ChannelEngine>> m_engines;
    // Everything the worker may still use when an exception unwinds is
    // declared before it (it stops first): the engines; pass 3's output
    // blocks, two so that the worker writes one while the next is filled
    // (as 16-bit samples too when the output takes them, converted here so
    // that the worker only writes); the pipeline's buffers (the worker may
    // be running the back of a block's last piece when the next block's
    // reading throws); pass 2's energies and peaks (which it may be adding
    // to).
    const bool m_pcm16;
    std::vector<float> m_out[2];
    std::vector<std::int16_t> m_out16[2];
    // The input's frames as read: its 16-bit samples when it gives them
    // (libsndfile's float of a 16-bit sample s is s·2^-15, exact, and so is
    // s·2^-15 as a double: the same x, without libsndfile's conversion),
    // else floats.
    const bool m_pcm16_in;
    std::vector<float> m_interleaved;
    std::vector<std::int16_t> m_interleaved16;
    std::vector<double> m_x, m_work, m_carrier, m_sum;
    std::vector<double> m_out_sq, m_max_abs;
    const double* m_sums = nullptr;  // the block's sums for `consume` (m_sum, or an engine's store)
    std::size_t m_current = 0;       // pass 3's output block being filled
    std::size_t m_unflushed = 0;     // frames written since the last start_writeback
    std::optional<PairWorker> m_worker;
};

StreamPasses::StreamPasses(AudioSource& input, AudioSink& output, const VocoderSettings& s,
                           const StreamLimits& limits, const BandSetup& setup)
    : m_input(input), m_output(output), m_settings(s), m_nc(static_cast<std::size_t>(input.channels())),
      m_frames(input.frames()),
      m_block(whole_signal_only(s) ? m_frames : std::max<std::size_t>(1, std::min(limits.block_frames, m_frames))),
      m_pcm16(output.takes_pcm16()), m_pcm16_in(input.gives_pcm16()) {
    // What is stored from pass 1: everything when it fits in the budget, or
    // when the settings need the whole signal at once.
    const std::size_t per_frame = setup.filters.size() * m_nc * sizeof(float);
    const std::size_t stored =
        whole_signal_only(s) ? m_frames : std::min(m_frames, limits.store_bytes / per_frame);
    // Every channel gets channel 0's noise carrier: a dual-mono input stays
    // dual-mono (independent carriers would make it dichotic).
    for (std::size_t c = 0; c < m_nc; ++c)
        m_engines.push_back(std::make_unique<ChannelEngine>(s, input.sample_rate_hz(), setup.filters,
                                                            setup.centres, 0, stored, m_frames, true));
    const std::size_t stride = m_engines.front()->stride();
    for (std::size_t i = 0; i < 2; ++i) {
        m_out[i].resize(m_block * m_nc);
        if (m_pcm16) m_out16[i].resize(m_block * m_nc);
    }
    if (m_pcm16_in)
        m_interleaved16.resize(m_block * m_nc);
    else
        m_interleaved.resize(m_block * m_nc);
    m_x.resize(m_block);
    m_work.resize(m_block * stride);
    m_carrier.resize(m_block * stride);
    m_sum.resize(m_block);
    m_out_sq.assign(m_nc, 0.0);
    m_max_abs.assign(m_nc, 0.0);
    if (limits.threads >= 2 && m_engines.front()->fused() && m_block > ChannelPipeline::kPieceFrames &&
        m_frames > ChannelPipeline::kPieceFrames) {
        m_worker.emplace();
        for (auto& engine : m_engines) engine->use_worker(&*m_worker);
    }
}

void StreamPasses::read_frames(std::size_t offset, std::size_t count) {
    std::size_t got = 0;
    while (got < count) {
        const std::size_t n =
            m_pcm16_in ? m_input.read_pcm16(m_interleaved16.data() + (offset + got) * m_nc, count - got)
                       : m_input.read(m_interleaved.data() + (offset + got) * m_nc, count - got);
        if (n == 0)
            throw InputError(Diagnostic{"", 0, 0, "audio",
                                        fmt::format("expected {} frames, the input ended after fewer", m_frames)});
        got += n;
    }
}

void StreamPasses::deinterleave(std::size_t offset, std::size_t count, std::size_t c) {
    if (m_pcm16_in)
        for (std::size_t n = offset; n < offset + count; ++n)
            m_x[n] = m_interleaved16[n * m_nc + c] * (1.0 / 32768.0);
    else
        for (std::size_t n = offset; n < offset + count; ++n) m_x[n] = m_interleaved[n * m_nc + c];
}

std::vector<BandInfo> StreamPasses::measure(const std::vector<BandInfo>& bands) {
    // Channel 0's pipeline reads the block piece by piece as it goes (see
    // ChannelPipeline::Fill); the other channels' find it read.
    m_input.seek(0);
    for (std::size_t first = 0; first < m_frames; first += m_block) {
        const std::size_t count = std::min(m_block, m_frames - first);
        for (std::size_t c = 0; c < m_nc; ++c)
            m_engines[c]->measure(m_x.data(), first, count, m_work, m_carrier,
                                  [this, c](std::size_t offset, std::size_t n) {
                                      if (c == 0) read_frames(offset, n);
                                      deinterleave(offset, n, c);
                                  });
    }
    std::vector<std::vector<BandInfo>> measured(m_nc, bands);
    for (std::size_t c = 0; c < m_nc; ++c) m_engines[c]->finish_measure(m_frames, measured[c]);
    return measured[0];
}

// The input is read only past the store. With `keep`, the engines keep what
// sums fit for the next replay. `consume(c, first, count)` takes channel c's
// sums of a block (m_sums); `then_of(c)` is channel c's ChannelPipeline::Then
// for the sums made in the store, which then skip `consume`.
template <typename Consume, typename ThenOf>
void StreamPasses::replay(Consume&& consume, bool keep, ThenOf&& then_of) {
    for (auto& engine : m_engines) engine->begin_replay();
    const std::size_t stored = m_engines.front()->replay_from();  // the same for every channel
    if (stored < m_frames) m_input.seek(stored);
    for (std::size_t first = 0; first < m_frames; first += m_block) {
        const std::size_t count = std::min(m_block, m_frames - first);
        const std::size_t from_input = first + count > stored ? first + count - std::max(first, stored) : 0;
        // Read the frames past the store into their place in the block.
        if (from_input > 0) read_frames(count - from_input, from_input);
        for (std::size_t c = 0; c < m_nc; ++c) {
            if (from_input > 0) deinterleave(0, count, c);
            m_sums = m_engines[c]->kept_sums(first, count);
            if (!m_sums) {
                m_sums = m_engines[c]->replay(m_x.data(), first, count, m_sum.data(), m_work, m_carrier, nullptr,
                                              keep, then_of(c));
                if (!m_sums) continue;
            }
            consume(c, first, count);
        }
    }
}

// The energy is one chain of additions in frame order, as long as the sums
// of the stored rows take to make: so with the worker, the sums made in the
// store are added up there, by the worker: a stored block's while this
// thread sums the next block's rows, and a block past the store piece by
// piece after each piece's back, so that this thread goes on to the next
// block's input and fronts without waiting for the last back (the worker's
// jobs run one at a time, in order; a block added up here waits for the
// worker first).
OutputLevels StreamPasses::sum_levels() {
    replay(
        [this](std::size_t c, std::size_t, std::size_t count) {
            if (m_worker) m_worker->wait();
            add_energy_and_peak(m_sums, count, &m_out_sq[c], &m_max_abs[c]);
        },
        true,
        [this](std::size_t c) -> ChannelPipeline::Then {
            if (!m_worker) return {};
            return [sq = &m_out_sq[c], top = &m_max_abs[c]](const double* s, std::size_t n) {
                add_energy_and_peak(s, n, sq, top);
            };
        });
    if (m_worker) m_worker->wait();
    return output_levels();
}

OutputLevels StreamPasses::output_levels() const {
    OutputLevels levels;
    levels.gain.assign(m_nc, 1.0);
    levels.apply_gain.assign(m_nc, false);
    for (std::size_t c = 0; c < m_nc; ++c) {
        if (m_settings.match_output_rms && m_out_sq[c] > 0.0) {
            const double in_sq = m_engines[c]->in_sq();
            levels.gain[c] = std::sqrt(in_sq / m_out_sq[c]);
            levels.apply_gain[c] = true;
            if (c == 0) levels.output_gain_db = in_sq > 0.0 ? to_db(levels.gain[c]) : -INFINITY;
        }
        // Rounding is monotonic, so the peak of the scaled samples is the
        // scaled peak.
        levels.peak = std::max(levels.peak, levels.apply_gain[c] ? m_max_abs[c] * levels.gain[c] : m_max_abs[c]);
    }
    // No clipping: scale the whole output down when its peak exceeds full scale.
    constexpr double kMaxPeak = 0.999;
    if (levels.peak > 1.0) {
        levels.scale = kMaxPeak / levels.peak;
        levels.limit_gain_db = to_db(levels.scale);
        log_debug("vocoder: output peak {:.3f} exceeds full scale; scaled the whole output by {:.2f} dB "
                    "to avoid clipping",
                    levels.peak, levels.limit_gain_db);
    }
    return levels;
}

// Block k is written on the worker, when there is one, while block k + 1 is
// filled, into the other buffer (a pipeline that needs the worker waits for
// the write first).
void StreamPasses::write(const OutputLevels& levels) {
    m_current = 0;
    m_unflushed = 0;
    replay([&](std::size_t c, std::size_t first, std::size_t count) { output_block(levels, c, first, count); },
           false, [](std::size_t) { return ChannelPipeline::Then{}; });
    if (m_worker) m_worker->wait();
}

void StreamPasses::output_block(const OutputLevels& levels, std::size_t c, std::size_t first, std::size_t count) {
    float* o = m_out[m_current].data();
    const double g = levels.gain[c];
    const double scale = levels.scale;
    if (levels.apply_gain[c])
        for (std::size_t n = 0; n < count; ++n) o[n * m_nc + c] = static_cast<float>(m_sums[n] * g * scale);
    else
        for (std::size_t n = 0; n < count; ++n) o[n * m_nc + c] = static_cast<float>(m_sums[n] * scale);
    if (c + 1 == m_nc) write_block(first, count);
}

void StreamPasses::write_block(std::size_t first, std::size_t count) {
    // Every so many frames, this thread starts the disk writes of what the
    // worker wrote (while it writes the next block), so that the output's
    // fsync at the end waits for the last few only.
    constexpr std::size_t kWritebackFrames = std::size_t{1} << 21;
    float* o = m_out[m_current].data();
    std::int16_t* o16 = m_out16[m_current].data();
    if (m_pcm16) float_to_pcm16(o, count * m_nc, o16);
    if (!m_worker) {
        m_pcm16 ? m_output.write_pcm16(o16, count) : m_output.write(o, count);
        return;
    }
    if (m_unflushed >= kWritebackFrames) {
        m_unflushed = 0;
        m_output.start_writeback();
    }
    // (start waits for the block before's write.) The worker then gives
    // back the store's memory of the sums read so far.
    auto done_with = [&engines = m_engines, end = first + count] {
        for (auto& engine : engines) engine->done_with(end);
    };
    AudioSink& output = m_output;
    if (m_pcm16)
        m_worker->start([&output, o16, count, done_with] {
            output.write_pcm16(o16, count);
            done_with();
        });
    else
        m_worker->start([&output, o, count, done_with] {
            output.write(o, count);
            done_with();
        });
    m_unflushed += count;
    m_current = 1 - m_current;
}

// vocode_channel's steps: pass 1 over the blocks, then the level-matched
// sums (and band signals) in one replay, then the overall gain.
void measure_channel(ChannelEngine& engine, std::span<const double> x, std::size_t block, std::vector<double>& work,
                     std::vector<double>& carrier) {
    for (std::size_t first = 0; first < x.size(); first += block)
        engine.measure(x.data() + first, first, std::min(block, x.size() - first), work, carrier);
}

void replay_channel(ChannelEngine& engine, std::span<const double> x, std::size_t block, std::vector<double>& work,
                    std::vector<double>& carrier, ChannelResult& result, bool keep_band_signals) {
    const std::size_t frames = x.size();
    std::vector<std::vector<double>> band_signals;
    if (keep_band_signals) band_signals.assign(engine.lanes(), std::vector<double>(frames));
    engine.begin_replay();
    for (std::size_t first = 0; first < frames; first += block) {
        const std::size_t count = std::min(block, frames - first);
        engine.replay(x.data() + first, first, count, result.samples.data() + first, work, carrier,
                      keep_band_signals ? &band_signals : nullptr);
    }
    result.band_signals = std::move(band_signals);
}

// The cochlear-implant simulation (ci_simulation.h) runs on the whole
// signal: the source read into memory, vocoded, written to the sink.
VocoderReport vocode_whole_signal(AudioSource& input, AudioSink& output, const VocoderSettings& s) {
    Audio audio;
    audio.sample_rate_hz = input.sample_rate_hz();
    audio.channels = input.channels();
    audio.samples.resize(input.frames() * static_cast<std::size_t>(audio.channels));
    input.seek(0);
    std::size_t read = 0;
    while (read < input.frames()) {
        const std::size_t got = input.read(audio.samples.data() + read * static_cast<std::size_t>(audio.channels),
                                           input.frames() - read);
        if (got == 0) break;
        read += got;
    }
    audio.samples.resize(read * static_cast<std::size_t>(audio.channels));
    const VocoderResult result = vocode_reference(audio, s);
    output.write(result.audio.samples.data(), result.audio.frames());
    VocoderReport report;
    report.bands = result.bands;
    report.output_gain_db = result.output_gain_db;
    report.peak_before_limit = result.peak_before_limit;
    report.limit_gain_db = result.limit_gain_db;
    report.selection = result.selection;
    return report;
}

void match_output_rms(ChannelResult& result, double in_sq, const VocoderSettings& s) {
    double out_sq = 0.0;
    for (double v : result.samples) out_sq += v * v;
    if (!s.match_output_rms || !(out_sq > 0.0)) return;
    const double gain = std::sqrt(in_sq / out_sq);
    for (double& v : result.samples) v *= gain;
    result.output_gain_db = in_sq > 0.0 ? to_db(gain) : -INFINITY;
}

}  // namespace

ChannelResult vocode_channel_in_blocks(std::span<const double> x, double rate, const VocoderSettings& s,
                                       int channel, bool keep_band_signals, std::size_t block_frames) {
    if (uses_ci_simulation(s)) return vocode_channel_reference(x, rate, s, channel, keep_band_signals);
    validate_settings(s, rate);
    const std::size_t frames = x.size();
    const BandSetup setup = band_setup(s, rate);
    ChannelResult result;
    result.bands = setup.bands;
    result.samples.assign(frames, 0.0);
    if (frames == 0) return result;
    const std::size_t block =
        whole_signal_only(s) ? frames : std::max<std::size_t>(1, std::min(block_frames, frames));
    ChannelEngine engine(s, rate, setup.filters, setup.centres, channel, frames, frames, false);
    std::vector<double> work(block * engine.stride()), carrier(block * engine.stride());
    measure_channel(engine, x, block, work, carrier);
    engine.finish_measure(frames, result.bands);
    replay_channel(engine, x, block, work, carrier, result, keep_band_signals);
    match_output_rms(result, engine.in_sq(), s);
    return result;
}

namespace {

// What makes the settings hold the whole signal, for the refusal.
const char* whole_signal_reason(const VocoderSettings& s) {
    if (uses_ci_simulation(s)) return "the cochlear-implant simulation";
    if (s.zero_phase) return "zero-phase filtering";
    if (s.envelope == EnvelopeMethod::Hilbert) return "Hilbert envelopes";
    return "the low-noise carrier";
}

// Refuses a signal whose whole-signal path would not fit in memory.
void check_memory(const VocoderSettings& s, std::size_t frames, int channels, int rate_hz) {
    const std::uint64_t need = whole_signal_memory_bytes(s, frames, channels);
    if (need == 0) return;  // streams: the common case reads no /proc file
    const std::uint64_t available = available_memory_bytes();
    if (need <= available) return;
    constexpr double kGb = 1e9;
    throw InputError(Diagnostic{
        "", 0, 0, "audio",
        fmt::format("{} holds the whole signal in memory: about {:.1f} GB for these {:.1f} minutes, and {:.1f} GB "
                    "is available; vocode the file in parts (sox in.wav part.wav trim 0 600 : newfile : restart "
                    "gives 10-minute parts) or with settings that stream (the noise or sine carrier, causal "
                    "filters, rectified envelopes, no CI stages)",
                    whole_signal_reason(s), double(need) / kGb, double(frames) / rate_hz / 60.0,
                    double(available) / kGb)});
}

}  // namespace

VocoderReport vocode_stream(AudioSource& input, AudioSink& output, const VocoderSettings& s,
                            const StreamLimits& limits) {
    check_source(input);
    validate_settings(s, input.sample_rate_hz());
    check_memory(s, input.frames(), input.channels(), input.sample_rate_hz());
    if (uses_ci_simulation(s)) return vocode_whole_signal(input, output, s);
    const BandSetup setup = band_setup(s, input.sample_rate_hz());
    VocoderReport report;
    report.bands = setup.bands;
    if (input.frames() == 0) return report;
    StreamPasses passes(input, output, s, limits, setup);
    report.bands = passes.measure(setup.bands);
    const OutputLevels levels = passes.sum_levels();
    report.output_gain_db = levels.output_gain_db;
    report.peak_before_limit = levels.peak;
    report.limit_gain_db = levels.limit_gain_db;
    passes.write(levels);
    return report;
}

}  // namespace detail

ChannelResult vocode_channel(std::span<const double> x, double rate, const VocoderSettings& s, int channel,
                             bool keep_band_signals) {
    return detail::vocode_channel_in_blocks(x, rate, s, channel, keep_band_signals, 512);
}

// One thread: these are called by code that runs several at once (stimulus
// builds, batches); `avsi vocode` of one file asks for two (batch.cpp).
std::uint64_t whole_signal_memory_bytes(const VocoderSettings& settings, std::size_t frames, int channels) {
    if (!uses_ci_simulation(settings) && !detail::whole_signal_only(settings)) return 0;
    const auto bands = static_cast<std::uint64_t>(std::max(settings.bands, 1));
    return static_cast<std::uint64_t>(frames) * static_cast<std::uint64_t>(std::max(channels, 1)) * (32 * bands + 130);
}

VocoderReport vocode_stream(AudioSource& input, AudioSink& output, const VocoderSettings& settings) {
    detail::StreamLimits limits;
    limits.threads = 1;
    return detail::vocode_stream(input, output, settings, limits);
}

VocoderResult vocode(const Audio& input, const VocoderSettings& settings) {
    AudioBufferSource source(input);
    VocoderResult result;
    result.audio.sample_rate_hz = input.sample_rate_hz;
    result.audio.channels = input.channels;
    result.audio.samples.reserve(input.samples.size());
    AudioBufferSink sink(result.audio);
    detail::StreamLimits limits;
    limits.threads = 1;
    VocoderReport report = detail::vocode_stream(source, sink, settings, limits);
    result.bands = std::move(report.bands);
    result.output_gain_db = report.output_gain_db;
    result.peak_before_limit = report.peak_before_limit;
    result.limit_gain_db = report.limit_gain_db;
    result.selection = std::move(report.selection);
    return result;
}

}  // namespace avsi::vocoder
