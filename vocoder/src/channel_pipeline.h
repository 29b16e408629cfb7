// Steps 1–4 of the channel vocoder (reference.cpp has them one band at a
// time, as equations) for all bands of one channel at once and for a signal
// that comes in blocks: the filter states and noise streams carry over from
// one block to the next, so any block length gives the same values.
//
// The bands run side by side as the lanes of SosBanks (4 lanes to a chunk;
// padding lanes give zero). Two ways through a block, the same values bit
// for bit:
//   - the plain way (run_plain): one bank after the other over the block;
//     any settings, and the only way for those that need the whole signal
//     at once (zero phase, Hilbert envelopes, low-noise carriers), which
//     then come as a single block;
//   - the fused loop of fused_pipeline.h, for the common settings: one pass
//     over the samples with the filter states in registers, on one thread,
//     or on two with a PairWorker (pair_worker.h) for blocks of more than
//     one 4096-frame piece: with one chunk of bands this thread runs each
//     piece's front (steps 1–2) and the worker its back (steps 3–4), as a
//     pipeline; with two or more chunks each thread takes half the chunks.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/vocoder.h"
#include "fused_pipeline.h"

namespace avsi::vocoder::detail {

class PairWorker;
class StoreBuffer;

// Zero-phase filtering, Hilbert envelopes and low-noise carriers need the
// whole signal at once.
bool whole_signal_only(const VocoderSettings& settings);

// The band-pass and envelope filters of one channel, their states and the
// carriers' streams, so the signal can run through steps 1–4 block by block.
// A copy, taken settled (see run), carries on from where the original was.
struct ChannelPipeline {
    // `channel` selects the noise streams: Rng(seed).derive("channel<c>/band<b>").
    ChannelPipeline(const VocoderSettings& s, double rate_hz, const std::vector<Sos>& band_filters, int channel);

    static constexpr std::size_t kPieceFrames = 4096;

    // Makes x[offset, offset + count) ready (x as run gets it). With the
    // worker, run calls it piece by piece, in order, just before the piece
    // is read, so that this thread reads the input while the worker runs
    // the back of the piece before; otherwise once for the whole block.
    // Empty: x is ready.
    using Fill = std::function<void(std::size_t offset, std::size_t count)>;
    // Given to run with sums asked for: called with the sums of each piece
    // of the block (where they are, and how many), in order, once they are
    // there: on the worker when it makes them (and then run does not wait
    // for them), else on this thread before run returns.
    using Then = std::function<void(const double* sums, std::size_t count)>;

    // Steps 1–4 for `frames` rows starting at absolute frame `first` (x[0],
    // made ready by `fill`): `work` gets the input broadcast to every lane
    // on entry and the filtered modulated carriers on exit; `carrier` is
    // scratch. `rows` says what becomes of the band outputs (FusedBlock's
    // fields from out_sum_sq on; x, carrier, work, frames and
    // analysis_sum_sq are filled in here): the same with the fused loop or
    // without.
    // With one chunk of bands on two threads and no sums asked for, the
    // worker may still be running the backs of the last pieces when this
    // returns: beside the next block's reading and first front (which waits
    // until the back is past piece 0, whose part of `work` and `carrier` it
    // rewrites). Their rows and sums of squares are there after settle();
    // every other use of the pipeline's state settles first. So may the
    // backs that make sums, when `then` takes them.
    void run(const double* x, std::size_t first, std::size_t frames, std::vector<double>& work,
             std::vector<double>& carrier, const std::vector<double>& centres_hz, FusedBlock rows,
             const Fill& fill = {}, const Then& then = {});

    // Waits for what the worker may still be running (see run).
    void settle();

    const VocoderSettings& settings;
    double rate;
    std::size_t lanes;
    SosBank bands;
    SosBank envelope_lowpass;
    SosBank::State analysis_state, envelope_state, prefilter_state, refilter_state;
    // One noise stream per band, run four side by side: xoshiro256** states
    // [chunk][word][4] (padding lanes all zero), and the current 64-bit draw
    // per lane.
    std::vector<std::uint64_t> noise_state;
    std::vector<std::uint64_t> noise_draw;
    std::vector<double> analysis_sum_sq;
    bool fused;  // steps 1–4 in the fused loop (fused_pipeline.h)
    // With the fused loop: a block of more than one piece runs on two
    // threads (see the file comment); null: one thread.
    PairWorker* worker = nullptr;
    // With one chunk of bands on two threads: the store the worker faults in
    // ahead while it waits for a front (StoreBuffer::populate_ahead; null:
    // none).
    StoreBuffer* ahead = nullptr;
    // With one chunk of bands on two threads: the pieces of the block whose
    // front this thread has done and whose back the worker has (a copy of
    // the pipeline, taken settled, starts afresh).
    struct PieceCounts {
        std::atomic<unsigned> fronts{0}, backs{0};
        std::atomic<bool> abandoned{false};  // this thread stopped at an exception
        PieceCounts() = default;
        PieceCounts(const PieceCounts&) {}
        PieceCounts& operator=(const PieceCounts&) { return *this; }
    } piece_counts;
    // run_split's scratch per side (work, then carrier).
    std::vector<double> split_scratch[2];

private:
    // How run_split divides a block: chunks [0, split) here, [split, chunks)
    // on the worker, in pieces of piece_frames.
    struct Split {
        std::size_t chunks, split, piece_frames, pieces;
        bool staggered;  // the worker a piece behind (see run_split)
    };

    FusedBanks fused_banks();

    // Runs a bank over `frames` rows: forward with carried state when the
    // signal comes in blocks, forward and backward over the whole signal
    // for zero phase.
    void filter(const SosBank& bank, SosBank::State& state, double* data, std::size_t frames);

    // Fills `carrier` (frames × stride) for the frames from `first` on.
    void make_carrier(double* carrier, std::size_t first, std::size_t frames, const std::vector<double>& centres_hz);
    // The same for the lanes of chunks [chunk_begin, chunk_end) only, into
    // rows of `out_stride` whose column 0 is lane 0 of chunk_begin (padding
    // lanes are left as they are, or get 0).
    void make_carrier(double* carrier, std::size_t first, std::size_t frames, const std::vector<double>& centres_hz,
                      std::size_t chunk_begin, std::size_t chunk_end, std::size_t out_stride);
    void make_sine_carriers(double* carrier, std::size_t first, std::size_t frames,
                            const std::vector<double>& centres_hz, std::size_t lane_begin, std::size_t lane_end,
                            std::size_t stride) const;

    // The plain way: steps 1–4 bank by bank, then the rows.
    void run_plain(const double* x, std::size_t first, std::size_t frames, std::vector<double>& work,
                   std::vector<double>& carrier, const std::vector<double>& centres_hz, const FusedBlock& rows,
                   const Fill& fill, const Then& then);
    // Step 2's first half on `work` (frames × stride): rectification, or
    // each band's Hilbert envelope.
    void extract_envelopes(std::vector<double>& work, std::size_t frames) const;
    // The band outputs in `w` (frames × stride) as the fused loop leaves
    // them: the replay's sums, or the sums of squares and the float rows.
    void emit_rows(const double* w, std::size_t frames, const FusedBlock& rows, const Then& then) const;

    // The fused loop on this thread over the whole block.
    void run_fused_here(std::size_t first, std::size_t frames, double* carrier, const std::vector<double>& centres_hz,
                        const FusedBlock& rows, const Fill& fill, const Then& then);

    // One chunk of bands on two threads: this thread runs each piece's
    // front and the worker its back (which makes its carriers first), each
    // piece in its own part of work/carrier, as a pipeline: the worker takes
    // piece i once this thread has published its front, so that within the
    // block either side may run ahead of the other, and a piece that takes
    // long on one side is made up on the next ones instead of holding up the
    // other side at every piece.
    void run_front_and_back(std::size_t first, std::size_t frames, double* carrier,
                            const std::vector<double>& centres_hz, const FusedBlock& rows, const Fill& fill,
                            const Then& then);
    // The worker's side of run_front_and_back: the backs of every piece.
    void run_backs(const FusedBanks& banks, const FusedBlock& rows, std::size_t first, std::size_t frames,
                   double* carrier, const std::vector<double>& centres_hz, StoreBuffer* ahead_store,
                   const Then& then);

    // Two or more chunks of bands on two threads: the chunks [0, split)
    // here and [split, chunks) on the worker, piece by piece, each side with
    // scratch of its own (so the threads share no cache lines but those of
    // the rows and sums). The replay's sum adds the chunks in order, and the
    // rows kept put both sides' lanes in one cache line: then the worker
    // runs a piece behind (piece i − 1 beside this thread's piece i, whose
    // lines it does not touch); otherwise each side runs the whole block at
    // once.
    void run_split(const FusedBanks& banks, const FusedBlock& rows, std::size_t first, std::size_t frames,
                   const std::vector<double>& centres_hz, const Fill& fill);
    // Piece i of one side (0: this thread's chunks, 1: the worker's).
    void run_split_piece(const FusedBanks& banks, const FusedBlock& rows, const Split& plan, std::size_t first,
                         std::size_t frames, const std::vector<double>& centres_hz, std::size_t i, std::size_t side);
};

}  // namespace avsi::vocoder::detail
