// Steps 1–4 of one channel, block by block, on one thread or two; see
// channel_pipeline.h. The per-sample arithmetic is that of reference.cpp
// (and of fused_pipeline.cpp, which does it in one loop), in the same
// order, so every way gives the same values bit for bit.
#include "channel_pipeline.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/rng.h"
#include "avsi/vocoder/hilbert.h"
#include "pair_worker.h"
#include "store_buffer.h"

namespace avsi::vocoder::detail {

namespace {

// Runs a bank over interleaved data from zero state, forward and (zero-phase) backward.
void run_bank_whole(const SosBank& bank, std::vector<double>& data, std::size_t frames, bool zero_phase) {
    bank.process(data.data(), frames, false);
    if (zero_phase) bank.process(data.data(), frames, true);
}

// Lane `lane` of frames × stride interleaved data.
std::vector<double> lane_column(const std::vector<double>& data, std::size_t frames, std::size_t stride,
                                std::size_t lane) {
    std::vector<double> out(frames);
    for (std::size_t n = 0; n < frames; ++n) out[n] = data[n * stride + lane];
    return out;
}

void set_lane_column(std::vector<double>& data, std::size_t stride, std::size_t lane,
                     const std::vector<double>& values) {
    for (std::size_t n = 0; n < values.size(); ++n) data[n * stride + lane] = values[n];
}

// acc[j] += Σ_n data[n·stride + j]², four lanes at a time.
void add_squares(const double* data, std::size_t frames, std::size_t stride, double* acc) {
    for (std::size_t chunk = 0; chunk < stride; chunk += 4) {
        // Each lane sums in sample order starting from its running total, so
        // the result does not depend on how the signal was split into blocks.
        double a[4] = {acc[chunk], acc[chunk + 1], acc[chunk + 2], acc[chunk + 3]};
        for (std::size_t n = 0; n < frames; ++n)
            for (std::size_t j = 0; j < 4; ++j) a[j] += data[n * stride + chunk + j] * data[n * stride + chunk + j];
        for (std::size_t j = 0; j < 4; ++j) acc[chunk + j] = a[j];
    }
}

// Low-noise noise (Pumplin 1985; Kohlrausch, Fassel, van der Heijden et al.
// 1997) in every lane of `carrier`: band-limited noise divided by its own
// Hilbert envelope, then band-limited again, repeated; each round flattens
// the envelope further (reference.cpp: low_noise_carrier).
void make_low_noise(const SosBank& bank, std::vector<double>& carrier, std::size_t frames, std::size_t lanes,
                    int iterations, bool zero_phase) {
    const std::size_t stride = bank.stride();
    run_bank_whole(bank, carrier, frames, zero_phase);
    for (int it = 0; it < iterations; ++it) {
        for (std::size_t l = 0; l < lanes; ++l) {
            std::vector<double> band = lane_column(carrier, frames, stride, l);
            const std::vector<double> envelope = hilbert_envelope(band);
            double mean = 0.0;
            for (double e : envelope) mean += e;
            mean /= static_cast<double>(std::max<std::size_t>(frames, 1));
            const double floor = 1e-9 * std::max(mean, 1e-300);
            for (std::size_t n = 0; n < frames; ++n) band[n] /= std::max(envelope[n], floor);
            set_lane_column(carrier, stride, l, band);
        }
        run_bank_whole(bank, carrier, frames, zero_phase);
    }
}

// Piece i (of ChannelPipeline::kPieceFrames frames) of a block of `frames`
// rows of `stride` values.
FusedBlock piece_of(const FusedBlock& rows, std::size_t frames, std::size_t stride, std::size_t i) {
    FusedBlock p = rows;
    const std::size_t start = i * ChannelPipeline::kPieceFrames;
    p.frames = std::min(ChannelPipeline::kPieceFrames, frames - start);
    p.x += start;
    p.carrier += start * stride;
    p.work += start * stride;
    if (p.rows) p.rows += start * p.lanes;
    if (p.sum) p.sum += start;
    return p;
}

}  // namespace

bool whole_signal_only(const VocoderSettings& s) {
    return s.zero_phase || s.envelope == EnvelopeMethod::Hilbert || s.carrier == CarrierType::LowNoise;
}

ChannelPipeline::ChannelPipeline(const VocoderSettings& s, double rate_hz, const std::vector<Sos>& band_filters,
                                 int channel)
    : settings(s), rate(rate_hz), lanes(band_filters.size()), bands(band_filters),
      envelope_lowpass(
          std::vector<Sos>(lanes, butterworth_lowpass(s.envelope_filter_order, s.envelope_cutoff_hz, rate_hz))),
      analysis_state(bands.initial_state()), envelope_state(envelope_lowpass.initial_state()),
      prefilter_state(bands.initial_state()), refilter_state(bands.initial_state()),
      noise_state(bands.stride() * 4, 0), noise_draw(bands.stride(), 0), analysis_sum_sq(bands.stride(), 0.0),
      fused(!whole_signal_only(s) && fused_supported(bands, envelope_lowpass)) {
    constexpr std::size_t chunk = SosBank::chunk_lanes;
    for (std::size_t b = 0; b < lanes; ++b) {
        const Rng stream = Rng(s.seed).derive(fmt::format("channel{}/band{}", channel, b));
        for (std::size_t word = 0; word < 4; ++word)
            noise_state[(b / chunk * 4 + word) * chunk + b % chunk] = stream.state()[word];
    }
}

void ChannelPipeline::settle() {
    if (worker) worker->wait();
}

void ChannelPipeline::run(const double* x, std::size_t first, std::size_t frames, std::vector<double>& work,
                          std::vector<double>& carrier, const std::vector<double>& centres_hz, FusedBlock rows,
                          const Fill& fill, const Then& then) {
    rows.x = x;
    rows.carrier = carrier.data();
    rows.work = work.data();
    rows.frames = frames;
    rows.analysis_sum_sq = analysis_sum_sq.data();
    if (!fused) {
        settle();
        run_plain(x, first, frames, work, carrier, centres_hz, rows, fill, then);
    } else if (!worker || frames <= kPieceFrames) {
        settle();
        run_fused_here(first, frames, carrier.data(), centres_hz, rows, fill, then);
    } else if (bands.stride() / SosBank::chunk_lanes >= 2) {
        settle();
        run_split(fused_banks(), rows, first, frames, centres_hz, fill);
        if (then) then(rows.sum, frames);
    } else {
        run_front_and_back(first, frames, carrier.data(), centres_hz, rows, fill, then);
    }
}

FusedBanks ChannelPipeline::fused_banks() {
    return FusedBanks{&bands,
                      &envelope_lowpass,
                      &analysis_state,
                      &envelope_state,
                      settings.prefilter_carrier ? &prefilter_state : nullptr,
                      settings.refilter_carrier ? &refilter_state : nullptr,
                      settings.envelope == EnvelopeMethod::FullWaveRectify};
}

void ChannelPipeline::filter(const SosBank& bank, SosBank::State& state, double* data, std::size_t frames) {
    if (settings.zero_phase) {
        bank.process(data, frames, false);
        bank.process(data, frames, true);
    } else {
        bank.process(data, frames, state);
    }
}

// ------------------------------------------------------------- carriers

void ChannelPipeline::make_carrier(double* carrier, std::size_t first, std::size_t frames,
                                   const std::vector<double>& centres_hz) {
    make_carrier(carrier, first, frames, centres_hz, 0, bands.stride() / SosBank::chunk_lanes, bands.stride());
}

void ChannelPipeline::make_carrier(double* carrier, std::size_t first, std::size_t frames,
                                   const std::vector<double>& centres_hz, std::size_t chunk_begin,
                                   std::size_t chunk_end, std::size_t out_stride) {
    const std::size_t stride = out_stride;
    const std::size_t lane_begin = chunk_begin * SosBank::chunk_lanes;
    const std::size_t lane_end = std::min(lanes, chunk_end * SosBank::chunk_lanes);
    switch (settings.carrier) {
        case CarrierType::Noise:
        case CarrierType::LowNoise:
            // Two uniform values in [-1, 1) with 32-bit resolution per
            // 64-bit draw; the stream position is absolute (`first`), so
            // an odd block start uses the second half of a draw.
            noise_carriers(noise_state.data(), noise_draw.data(), lanes, chunk_begin, chunk_end, stride, first,
                           frames, carrier);
            if (settings.carrier == CarrierType::LowNoise) {
                AVSI_ASSERT(lane_begin == 0 && stride == bands.stride());
                // Whole signal only (whole_signal_only): Hilbert envelopes need it.
                std::vector<double> whole(carrier, carrier + frames * stride);
                make_low_noise(bands, whole, frames, lanes, settings.low_noise_iterations, settings.zero_phase);
                std::copy(whole.begin(), whole.end(), carrier);
            }
            break;
        case CarrierType::Sine:
            make_sine_carriers(carrier, first, frames, centres_hz, lane_begin, lane_end, stride);
            break;
        case CarrierType::PulseTrain:
        case CarrierType::PoissonPulses:
        case CarrierType::Pshc:
            // uses_ci_simulation: every entry point runs ci_simulation.cpp instead.
            AVSI_ASSERT(false);  // pulse carriers run on the CI path (ci_simulation.cpp)
            break;
    }
}

// sin(ω·t) at each band's centre frequency, by a rotating phasor that is
// re-anchored to the exact sin/cos every 1024 samples of absolute time (so
// blocks do not matter).
void ChannelPipeline::make_sine_carriers(double* carrier, std::size_t first, std::size_t frames,
                                         const std::vector<double>& centres_hz, std::size_t lane_begin,
                                         std::size_t lane_end, std::size_t stride) const {
    for (std::size_t b = lane_begin; b < lane_end; ++b) {
        double* column = carrier + (b - lane_begin);
        const double w = 2.0 * std::numbers::pi * centres_hz[b] / rate;
        const std::complex<double> step = std::polar(1.0, w);
        // Start as a whole-signal run would: from the last anchor.
        const std::size_t anchor = first / 1024 * 1024;
        std::complex<double> phasor = std::polar(1.0, w * static_cast<double>(anchor));
        for (std::size_t t = anchor; t < first; ++t) phasor *= step;
        for (std::size_t n = 0; n < frames; ++n) {
            const std::size_t t = first + n;
            if (t % 1024 == 0) phasor = std::polar(1.0, w * static_cast<double>(t));
            column[n * stride] = phasor.imag();
            phasor *= step;
        }
    }
}

// ------------------------------------------------------------- the plain way

void ChannelPipeline::run_plain(const double* x, std::size_t first, std::size_t frames, std::vector<double>& work,
                                std::vector<double>& carrier, const std::vector<double>& centres_hz,
                                const FusedBlock& rows, const Fill& fill, const Then& then) {
    const std::size_t stride = bands.stride();
    double* w = work.data();
    if (fill) fill(0, frames);
    if (rows.in_sum_sq)
        for (std::size_t n = 0; n < frames; ++n) *rows.in_sum_sq += x[n] * x[n];
    // Padding lanes get the input too; their filters output zero.
    for (std::size_t n = 0; n < frames; ++n) std::fill_n(w + n * stride, stride, x[n]);
    // 1. Analysis.
    filter(bands, analysis_state, w, frames);
    add_squares(w, frames, stride, analysis_sum_sq.data());
    // 2. Envelope.
    extract_envelopes(work, frames);
    filter(envelope_lowpass, envelope_state, w, frames);
    // 3. Carrier.
    double* c = carrier.data();
    make_carrier(c, first, frames, centres_hz);
    if (settings.prefilter_carrier) filter(bands, prefilter_state, c, frames);
    // 4. Modulation (envelope floored at zero), then back through the band.
    for (std::size_t i = 0; i < frames * stride; ++i) w[i] = std::max(w[i], 0.0) * c[i];
    if (settings.refilter_carrier) filter(bands, refilter_state, w, frames);
    emit_rows(w, frames, rows, then);
}

void ChannelPipeline::extract_envelopes(std::vector<double>& work, std::size_t frames) const {
    const std::size_t stride = bands.stride();
    double* w = work.data();
    switch (settings.envelope) {
        case EnvelopeMethod::HalfWaveRectify:
            for (std::size_t i = 0; i < frames * stride; ++i) w[i] = std::max(w[i], 0.0);
            break;
        case EnvelopeMethod::FullWaveRectify:
            for (std::size_t i = 0; i < frames * stride; ++i) w[i] = std::abs(w[i]);
            break;
        case EnvelopeMethod::Hilbert:  // whole signal only
            for (std::size_t b = 0; b < lanes; ++b)
                set_lane_column(work, stride, b, hilbert_envelope(lane_column(work, frames, stride, b)));
            break;
    }
}

void ChannelPipeline::emit_rows(const double* w, std::size_t frames, const FusedBlock& rows, const Then& then) const {
    const std::size_t stride = bands.stride();
    if (rows.sum) {
        for (std::size_t n = 0; n < frames; ++n) {
            double s = 0.0;
            for (std::size_t b = 0; b < stride; ++b) s += rows.gains[b] * static_cast<float>(w[n * stride + b]);
            rows.sum[n] = s;
        }
        if (then) then(rows.sum, frames);
        return;
    }
    if (rows.out_sum_sq) add_squares(w, frames, stride, rows.out_sum_sq);
    if (rows.rows)
        for (std::size_t n = 0; n < frames; ++n)
            for (std::size_t b = 0; b < rows.lanes; ++b)
                rows.rows[n * rows.lanes + b] = static_cast<float>(w[n * stride + b]);
}

// ------------------------------------------------------------- the fused loop

void ChannelPipeline::run_fused_here(std::size_t first, std::size_t frames, double* carrier,
                                     const std::vector<double>& centres_hz, const FusedBlock& rows, const Fill& fill,
                                     const Then& then) {
    if (fill) fill(0, frames);
    make_carrier(carrier, first, frames, centres_hz);
    run_fused(fused_banks(), rows);
    if (then) then(rows.sum, frames);
}

void ChannelPipeline::run_front_and_back(std::size_t first, std::size_t frames, double* carrier,
                                         const std::vector<double>& centres_hz, const FusedBlock& rows,
                                         const Fill& fill, const Then& then) {
    const FusedBanks banks = fused_banks();
    const std::size_t stride = bands.stride();
    auto front = [&](std::size_t i) {
        const FusedBlock p = piece_of(rows, frames, stride, i);
        if (fill) fill(i * kPieceFrames, p.frames);
        run_fused_front(banks, p);
    };
    const std::size_t pieces = (frames + kPieceFrames - 1) / kPieceFrames;
    // Piece 0's front beside the end of the block before, when its back was
    // left running, once that is past piece 0.
    if (worker->running_for(this))
        worker->caller_side().await(piece_counts.backs, 1);
    else
        worker->wait();
    front(0);
    worker->wait();
    piece_counts.fronts.store(1, std::memory_order_relaxed);  // published by start
    piece_counts.backs.store(0, std::memory_order_relaxed);
    piece_counts.abandoned.store(false, std::memory_order_relaxed);
    // The job may outlive this call (see run): it holds copies, and `ahead` as it is now.
    worker->start([this, banks, rows, first, frames, carrier, &centres_hz, ahead_store = ahead,
                   then] { run_backs(banks, rows, first, frames, carrier, centres_hz, ahead_store, then); },
                  this);
    for (std::size_t i = 1; i < pieces; ++i) {
        try {
            front(i);
        } catch (...) {
            piece_counts.abandoned.store(true, std::memory_order_relaxed);
            HandOver::bump(piece_counts.fronts);
            worker->wait();
            throw;
        }
        HandOver::bump(piece_counts.fronts);
    }
    // The sums are read when this returns, unless `then` takes them.
    if (rows.sum && !then) worker->wait();
}

void ChannelPipeline::run_backs(const FusedBanks& banks, const FusedBlock& rows, std::size_t first,
                                std::size_t frames, double* carrier, const std::vector<double>& centres_hz,
                                StoreBuffer* ahead_store, const Then& then) {
    HandOver& side = worker->worker_side();
    const std::size_t stride = bands.stride();
    const std::size_t pieces = (frames + kPieceFrames - 1) / kPieceFrames;
    for (std::size_t i = 0; i < pieces; ++i) {
        const unsigned target = static_cast<unsigned>(i + 1);
        // While the front is not there: fault in the store ahead.
        if (ahead_store)
            while (static_cast<int>(piece_counts.fronts.load(std::memory_order_acquire) - target) < 0 &&
                   ahead_store->populate_ahead()) {
            }
        side.await(piece_counts.fronts, target);
        if (piece_counts.abandoned.load(std::memory_order_relaxed)) return;
        const FusedBlock p = piece_of(rows, frames, stride, i);
        make_carrier(carrier + i * kPieceFrames * stride, first + i * kPieceFrames, p.frames, centres_hz);
        run_fused_back(banks, p);
        HandOver::bump(piece_counts.backs);
        if (then) then(p.sum, p.frames);
    }
}

void ChannelPipeline::run_split(const FusedBanks& banks, const FusedBlock& rows, std::size_t first,
                                std::size_t frames, const std::vector<double>& centres_hz, const Fill& fill) {
    constexpr std::size_t kLanes = SosBank::chunk_lanes;
    Split plan;
    plan.chunks = bands.stride() / kLanes;
    plan.split = (plan.chunks + 1) / 2;
    plan.staggered = rows.sum || rows.rows;
    plan.piece_frames = plan.staggered ? kPieceFrames / 2 : kPieceFrames;
    plan.pieces = (frames + plan.piece_frames - 1) / plan.piece_frames;
    // Work then carrier, per side; zero at first (padding lanes' carriers
    // stay 0 with sine carriers, which fill only the bands).
    for (std::size_t side = 0; side < 2; ++side) {
        const std::size_t lanes_of_side = (side == 0 ? plan.split : plan.chunks - plan.split) * kLanes;
        if (split_scratch[side].size() != 2 * kPieceFrames * lanes_of_side)
            split_scratch[side].assign(2 * kPieceFrames * lanes_of_side, 0.0);
    }
    auto piece = [&](std::size_t i, std::size_t side) {
        run_split_piece(banks, rows, plan, first, frames, centres_hz, i, side);
    };
    if (!plan.staggered) {
        // Each side the whole block at once.
        if (fill) fill(0, frames);
        worker->start([&piece, &plan] {
            for (std::size_t i = 0; i < plan.pieces; ++i) piece(i, 1);
        });
        try {
            for (std::size_t i = 0; i < plan.pieces; ++i) piece(i, 0);
        } catch (...) {
            worker->wait();
            throw;
        }
        worker->wait();
        return;
    }
    // The worker a piece behind.
    for (std::size_t i = 0; i <= plan.pieces; ++i) {
        if (i > 0) worker->start([&piece, i] { piece(i - 1, 1); });
        if (i < plan.pieces) {
            try {
                if (fill) fill(i * plan.piece_frames, std::min(plan.piece_frames, frames - i * plan.piece_frames));
                piece(i, 0);
            } catch (...) {
                if (i > 0) worker->wait();
                throw;
            }
        }
        if (i > 0) worker->wait();
    }
}

void ChannelPipeline::run_split_piece(const FusedBanks& banks, const FusedBlock& rows, const Split& plan,
                                      std::size_t first, std::size_t frames, const std::vector<double>& centres_hz,
                                      std::size_t i, std::size_t side) {
    constexpr std::size_t kLanes = SosBank::chunk_lanes;
    FusedBlock p = rows;
    const std::size_t start = i * plan.piece_frames;
    p.frames = std::min(plan.piece_frames, frames - start);
    p.x += start;
    if (p.rows) p.rows += start * p.lanes;
    if (p.sum) p.sum += start;
    if (side == 1) p.in_sum_sq = nullptr;  // chunk 0's
    p.chunk_begin = side == 0 ? 0 : plan.split;
    p.chunk_end = side == 0 ? plan.split : plan.chunks;
    p.stride = (p.chunk_end - p.chunk_begin) * kLanes;
    double* work = split_scratch[side].data();
    double* carrier = work + kPieceFrames * p.stride;
    p.work = work;
    p.carrier = carrier;
    make_carrier(carrier, first + start, p.frames, centres_hz, p.chunk_begin, p.chunk_end, p.stride);
    run_fused(banks, p);
}

}  // namespace avsi::vocoder::detail
