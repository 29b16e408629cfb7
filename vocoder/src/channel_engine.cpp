// One channel's passes and its store; see channel_engine.h.
#include "channel_engine.h"

#include <cmath>
#include <cstring>
#include <type_traits>

#include "avsi/core/error.h"
#include "pair_worker.h"

namespace avsi::vocoder::detail {

ChannelEngine::ChannelEngine(const VocoderSettings& s, double rate, const std::vector<Sos>& band_filters,
                             const std::vector<double>& centres, int channel, std::size_t stored_frames,
                             std::size_t frames, bool keep_sums)
    : m_settings(s), m_centres(centres), m_pipeline(s, rate, band_filters, channel), m_lanes(band_filters.size()),
      m_stride(m_pipeline.bands.stride()), m_stored(stored_frames), m_summed(m_stored),
      m_store(stored_frames * m_lanes * sizeof(float)), m_out_sum_sq(m_stride, 0.0) {
    const std::size_t sum_room = stored_frames * m_lanes * sizeof(float) / sizeof(double);
    if (keep_sums && m_stored < frames && sum_room > m_stored) m_summed = std::min(frames, sum_room);
}

void ChannelEngine::measure(const double* x, std::size_t first, std::size_t count, std::vector<double>& work,
                            std::vector<double>& carrier, const ChannelPipeline::Fill& fill) {
    // Split at the end of the store and of the sums: replay pipelines start there.
    for (std::size_t edge : {m_stored, m_summed}) {
        if (first < edge && first + count > edge) {
            const std::size_t head = edge - first;
            measure(x, first, head, work, carrier, fill);
            ChannelPipeline::Fill rest;
            if (fill) rest = [&fill, head](std::size_t offset, std::size_t n) { fill(head + offset, n); };
            measure(x + head, edge, count - head, work, carrier, rest);
            return;
        }
    }
    m_pipeline.ahead = nullptr;  // (replay copies start without)
    if (first == m_stored || (first == m_summed && m_summed > m_stored)) m_pipeline.settle();
    if (first == m_stored) m_replay_start.emplace(m_pipeline);
    if (first == m_summed && m_summed > m_stored) m_final_start.emplace(m_pipeline);
    FusedBlock rows;
    rows.out_sum_sq = m_out_sum_sq.data();
    rows.in_sum_sq = &m_in_sq;
    if (first < m_stored) {
        rows.rows = rows_at(first);
        m_store.make_ready((first + count) * m_lanes * sizeof(float));
        m_pipeline.ahead = &m_store;
    }
    rows.lanes = m_lanes;
    m_pipeline.run(x, first, count, work, carrier, m_centres, rows, fill);
}

void ChannelEngine::finish_measure(std::size_t frames, std::vector<BandInfo>& bands) {
    m_pipeline.settle();
    m_gains.assign(m_stride, 0.0);  // padding lanes: 0
    const double count = static_cast<double>(frames);
    for (std::size_t b = 0; b < m_lanes; ++b) {
        m_gains[b] = 1.0;
        bands[b].analysis_rms = std::sqrt(m_pipeline.analysis_sum_sq[b] / count);
        const double rms = std::sqrt(m_out_sum_sq[b] / count);
        if (m_settings.match_band_rms && rms > 0.0) m_gains[b] = bands[b].analysis_rms / rms;
        bands[b].output_rms = rms * m_gains[b];
    }
    if (frames == m_stored) m_replay_start.reset();
}

void ChannelEngine::begin_replay() {
    if (m_summed > m_stored && m_sums_written == m_summed) m_sums_kept = true;
    if (m_sums_kept) {
        if (m_final_start) m_replay.emplace(*m_final_start);
    } else if (m_replay_start) {
        m_replay.emplace(*m_replay_start);
    }
}

const double* ChannelEngine::replay(const double* x, std::size_t first, std::size_t count, double* sum,
                                    std::vector<double>& work, std::vector<double>& carrier,
                                    std::vector<std::vector<double>>* band_signals, bool keep,
                                    const ChannelPipeline::Then& then) {
    // Sums kept, of a block wholly in the store or wholly past it: made in
    // their place in the store.
    if (keep && m_summed > m_stored && !m_sums_kept && !band_signals &&
        (first + count <= m_stored || (first >= m_stored && first + count <= m_summed)))
        return replay_into_store(x, first, count, work, carrier, then);
    replay_into(x, first, count, sum, work, carrier, band_signals, keep);
    return sum;
}

const double* ChannelEngine::replay_into_store(const double* x, std::size_t first, std::size_t count,
                                               std::vector<double>& work, std::vector<double>& carrier,
                                               const ChannelPipeline::Then& then) {
    AVSI_ASSERT(first == m_sums_written);
    unsigned char* to = m_store.get() + first * sizeof(double);
    const double* sums = reinterpret_cast<const double*>(to);
    m_sums_written += count;
    if (first < m_stored) {
        sum_rows(m_store.get() + first * m_lanes * sizeof(float), count, m_stride > m_lanes, to);
        if (!then) return sums;
        // On the worker while this thread sums the next block's rows.
        if (PairWorker* worker = m_pipeline.worker)
            worker->start([then, sums, count] { then(sums, count); });
        else
            then(sums, count);
        return nullptr;
    }
    // (Over rows this replay has read: it is past the store.)
    AVSI_ASSERT(m_replay);
    FusedBlock rows;
    rows.gains = m_gains.data();
    rows.sum = reinterpret_cast<double*>(to);
    m_replay->run(x, first, count, work, carrier, m_centres, rows, {}, then);
    return then ? nullptr : sums;
}

void ChannelEngine::replay_into(const double* x, std::size_t first, std::size_t count, double* sum,
                                std::vector<double>& work, std::vector<double>& carrier,
                                std::vector<std::vector<double>>* band_signals, bool keep) {
    // Split at the first frame computed again, and (keeping) at the end of the sums.
    const std::size_t from = replay_from();
    if (first < from && first + count > from) {
        const std::size_t head = from - first;
        replay_into(x, first, head, sum, work, carrier, band_signals, keep);
        replay_into(x + head, from, count - head, sum + head, work, carrier, band_signals, keep);
        return;
    }
    if (keep && m_summed > m_stored && first < m_summed && first + count > m_summed) {
        const std::size_t head = m_summed - first;
        replay_into(x, first, head, sum, work, carrier, band_signals, keep);
        replay_into(x + head, m_summed, count - head, sum + head, work, carrier, band_signals, keep);
        return;
    }
    if (m_sums_kept && first < m_summed) {
        std::memcpy(sum, m_store.get() + first * sizeof(double), count * sizeof(double));
        return;
    }
    if (first < m_stored) {
        // The sum as the pipeline's rows give it: over the stride's
        // lanes, whose padding lanes hold +0 with gain 0 and so add
        // +0.0 (which turns a -0 sum into +0).
        const float* rows = rows_at(first);
        sum_rows(reinterpret_cast<const unsigned char*>(rows), count, m_stride > m_lanes,
                 reinterpret_cast<unsigned char*>(sum));
        if (band_signals)
            for (std::size_t b = 0; b < m_lanes; ++b)
                for (std::size_t n = 0; n < count; ++n)
                    (*band_signals)[b][first + n] = m_gains[b] * rows[n * m_lanes + b];
    } else {
        AVSI_ASSERT(m_replay && !band_signals);
        FusedBlock rows;
        rows.gains = m_gains.data();
        rows.sum = sum;
        m_replay->run(x, first, count, work, carrier, m_centres, rows);
    }
    // Frame n's sum goes to bytes [8n, 8n + 8), which hold band outputs
    // of frames before n·8/(4·lanes) ≤ n only: read already.
    if (keep && m_summed > m_stored && first < m_summed) {
        AVSI_ASSERT(first == m_sums_written);
        std::memcpy(m_store.get() + first * sizeof(double), sum, count * sizeof(double));
        m_sums_written += count;
    }
}

void ChannelEngine::sum_rows(const unsigned char* rows, std::size_t count, bool padded, unsigned char* sum) const {
    auto row = [rows](std::size_t at) {
        float v;
        std::memcpy(&v, rows + at * sizeof(float), sizeof v);
        return static_cast<double>(v);
    };
    auto put = [sum](std::size_t n, double v) { std::memcpy(sum + n * sizeof(double), &v, sizeof v); };
    // The band count as a constant for 1–4 bands (0: m_lanes), so the loops unroll.
    auto run = [&](auto lanes_constant) {
        constexpr std::size_t L = decltype(lanes_constant)::value;
        const std::size_t lanes = L ? L : m_lanes;
        std::size_t n = 0;
        for (; n + 4 <= count; n += 4) {
            double s[4] = {0.0, 0.0, 0.0, 0.0};
            for (std::size_t b = 0; b < lanes; ++b)
                for (std::size_t j = 0; j < 4; ++j) s[j] += m_gains[b] * row((n + j) * lanes + b);
            for (std::size_t j = 0; j < 4; ++j) put(n + j, padded ? s[j] + 0.0 : s[j]);
        }
        for (; n < count; ++n) {
            double s = 0.0;
            for (std::size_t b = 0; b < lanes; ++b) s += m_gains[b] * row(n * lanes + b);
            put(n, padded ? s + 0.0 : s);
        }
    };
    switch (m_lanes) {
        case 1: run(std::integral_constant<std::size_t, 1>{}); break;
        case 2: run(std::integral_constant<std::size_t, 2>{}); break;
        case 3: run(std::integral_constant<std::size_t, 3>{}); break;
        case 4: run(std::integral_constant<std::size_t, 4>{}); break;
        default: run(std::integral_constant<std::size_t, 0>{}); break;
    }
}

}  // namespace avsi::vocoder::detail
