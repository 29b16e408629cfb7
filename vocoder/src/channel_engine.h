// One channel of the fast path through steps 1–5 in passes over its input,
// so that a long signal needs memory for a block, not for its length
// (vocode_stream.cpp runs the passes over every channel):
//   pass 1 (measure): steps 1–4 (channel_pipeline.h); the sums of squares
//     of each band before and after, and of the input; the band gains
//     g_b = rms(analysis_b) / rms(output_b) follow;
//   pass 2 (replay): the level-matched band sum s = Σ_b g_b·float(y_b), its
//     sum of squares and peak; the overall gain and the anti-clipping scale
//     follow;
//   pass 3 (replay again): the output.
// The band outputs of the first `stored` frames are kept from pass 1 in
// single precision (as the sum reads them) in a StoreBuffer; later frames
// are computed again by a copy of the pipeline taken at frame `stored`,
// which gives the same values (the pipeline is deterministic and block-length
// independent). With everything stored, the pipeline runs once.
// Pass 2 can keep its sums for pass 3 in the same memory (`keep_sums`): a
// frame's sum (8 bytes) takes less room than its band outputs (4 bytes per
// band) from 3 bands on, so the sums of the first `summed` frames fit
// (summed > stored) and pass 3 computes again only the frames past them,
// with a copy of the pipeline taken at frame `summed`.
#pragma once

#include <algorithm>
#include <cstddef>
#include <optional>
#include <vector>

#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/vocoder.h"
#include "channel_pipeline.h"
#include "store_buffer.h"

namespace avsi::vocoder::detail {

class ChannelEngine {
public:
    // `stored_frames` of the `frames` are kept from pass 1; `channel`
    // selects the noise streams (see ChannelPipeline).
    ChannelEngine(const VocoderSettings& s, double rate, const std::vector<Sos>& band_filters,
                  const std::vector<double>& centres, int channel, std::size_t stored_frames, std::size_t frames,
                  bool keep_sums);

    std::size_t lanes() const { return m_lanes; }
    std::size_t stride() const { return m_stride; }
    bool fused() const { return m_pipeline.fused; }
    // Runs the pipeline (and its copies) with a second thread (see ChannelPipeline::worker).
    void use_worker(PairWorker* worker) { m_pipeline.worker = worker; }
    // The first frame the next replay computes again (and so reads the input from).
    std::size_t replay_from() const { return m_sums_kept ? m_summed : m_stored; }

    // Pass 1 over frames [first, first + count) (x[0] is frame `first`,
    // made ready by `fill`, see ChannelPipeline::Fill); `work` and `carrier`
    // are scratch of count × stride.
    void measure(const double* x, std::size_t first, std::size_t count, std::vector<double>& work,
                 std::vector<double>& carrier, const ChannelPipeline::Fill& fill = {});

    // After pass 1 over all `frames`: the band gains and what was measured.
    void finish_measure(std::size_t frames, std::vector<BandInfo>& bands);

    // Starts a replay (pass 2 or 3) from frame 0.
    void begin_replay();

    // The level-matched band sum of frames [first, first + count) (x[0] is
    // frame `first`; read only from replay_from() on), in order from 0:
    // where it is, `sum` or (with `keep`, for a block wholly in the store or
    // wholly between its end and `summed`) its place in the store. With
    // `band_signals`, also each band's level-matched output. With `keep`,
    // the sums of frames before `summed` are kept for the next replay (which
    // then reads them); only in one replay over all frames. With `then` too,
    // the sums made in the store go to `then` instead, in order (see
    // ChannelPipeline::Then; on the worker when there is one), and this
    // returns null.
    const double* replay(const double* x, std::size_t first, std::size_t count, double* sum,
                         std::vector<double>& work, std::vector<double>& carrier,
                         std::vector<std::vector<double>>* band_signals = nullptr, bool keep = false,
                         const ChannelPipeline::Then& then = {});

    // Σ x² over the input, in frame order.
    double in_sq() const { return m_in_sq; }

    // The kept sums of frames [first, first + count) when the next replay
    // reads them all from the store, else null.
    const double* kept_sums(std::size_t first, std::size_t count) const {
        if (!m_sums_kept || first + count > m_summed) return nullptr;
        return reinterpret_cast<const double*>(m_store.get()) + first;
    }

    // In the last replay, once the sums of frames before `frame` are read
    // for the last time: their part of the store is given back (when the
    // replay reads kept sums; otherwise the store goes at the end).
    void done_with(std::size_t frame) {
        if (m_sums_kept) m_store.release(std::min(frame, m_summed) * sizeof(double));
    }

private:
    // replay of a block whose sums go into their place in the store.
    const double* replay_into_store(const double* x, std::size_t first, std::size_t count,
                                    std::vector<double>& work, std::vector<double>& carrier,
                                    const ChannelPipeline::Then& then);
    // replay's work, into `sum`.
    void replay_into(const double* x, std::size_t first, std::size_t count, double* sum, std::vector<double>& work,
                     std::vector<double>& carrier, std::vector<std::vector<double>>* band_signals, bool keep);

    float* rows_at(std::size_t frame) { return reinterpret_cast<float*>(m_store.get()) + frame * m_lanes; }

    // sum[n] = Σ_b gains[b]·rows[n][b] in band order from 0.0 (+ 0.0 when
    // padded); four frames at a time, each frame's operations in that order.
    // Through bytes (memcpy, which the compiler keeps in order with every
    // access that may overlap), so that `sum` may be the store over the rows
    // themselves: frame n's sum (bytes [8n, 8n + 8)) overwrites only rows of
    // frames f < 2(n + 1) / lanes ≤ n (sums are kept there from 3 bands
    // on), read in n's group of four or before it.
    void sum_rows(const unsigned char* rows, std::size_t count, bool padded, unsigned char* sum) const;

    const VocoderSettings& m_settings;
    const std::vector<double>& m_centres;
    ChannelPipeline m_pipeline;
    std::size_t m_lanes, m_stride, m_stored, m_summed;
    // [frame][band] floats of the first m_stored frames; after a replay
    // with `keep`, the doubles of the first m_summed frames' sums.
    StoreBuffer m_store;
    std::size_t m_sums_written = 0;  // by the replay with `keep`
    bool m_sums_kept = false;         // the next replays read them
    std::vector<double> m_out_sum_sq;
    double m_in_sq = 0.0;
    std::vector<double> m_gains;
    std::optional<ChannelPipeline> m_replay_start, m_final_start, m_replay;
};

}  // namespace avsi::vocoder::detail
