// Steps 1–4 of the channel vocoder (reference.cpp gives their equations;
// channel_pipeline.cpp runs them bank by bank) in one loop over the
// samples of a block, for the common settings: Butterworth band-pass bands
// (SosBank::Kind::BandPass) of `order` 4, a Butterworth envelope low-pass of
// order 4 (two LowPass2 sections), half- or full-wave rectification, causal
// filtering, and carriers given per sample. The same IEEE operations per lane
// as running the banks one after the other (SosBank::process), in the same
// order, so the output is identical bit for bit; in one loop the filter
// state stays in registers and the three filters' recursions overlap. Also
// the carriers' noise: xoshiro256** streams (avsi::Rng) run four side by side.
#pragma once

#include <cstddef>
#include <cstdint>

#include "avsi/vocoder/filters.h"

namespace avsi::vocoder::detail {

// One block through the fused steps 1–4, and what is done with each band
// output row r (stride lanes) on the way out: in a measuring pass its
// squares and the input's are summed and it is kept in single precision;
// in a replay pass the level-matched sum Σ_b gains[b]·float(r_b), summed over
// the lanes in order from 0.0, is written instead.
struct FusedBlock {
    const double* x = nullptr;        // frames inputs; each goes to every lane
    const double* carrier = nullptr;  // frames × stride carriers
    double* work = nullptr;           // frames × stride scratch
    std::size_t frames = 0;
    // The chunks (of SosBank::chunk_lanes lanes) run: [chunk_begin,
    // chunk_end), and the layout of `carrier` and `work`: rows of `stride`
    // values (0: the bank's stride) whose column 0 is lane 0 of chunk_begin.
    // The other fields are indexed by band whatever the range.
    std::size_t chunk_begin = 0;
    std::size_t chunk_end = SIZE_MAX;
    std::size_t stride = 0;
    double* analysis_sum_sq = nullptr;  // stride running sums of the analysis output squared
    // Measuring (each may be null):
    double* out_sum_sq = nullptr;  // stride running sums of r squared
    double* in_sum_sq = nullptr;   // running sum of x squared
    float* rows = nullptr;         // frames × lanes: float(r) of the bands (no padding lanes)
    std::size_t lanes = 0;         // bands, for `rows`
    // Replaying (both or neither):
    const double* gains = nullptr;  // stride (0 for padding lanes)
    double* sum = nullptr;          // frames sums
};
// The banks and their states; prefilter/refilter states null when off.
struct FusedBanks {
    const SosBank* bands = nullptr;
    const SosBank* envelope = nullptr;
    SosBank::State* analysis = nullptr;
    SosBank::State* envelope_state = nullptr;
    SosBank::State* prefilter = nullptr;
    SosBank::State* refilter = nullptr;
    bool full_wave = false;
};

// True when the fused loop handles these banks (kinds and section counts).
bool fused_supported(const SosBank& bands, const SosBank& envelope);

// Runs the block (fused_supported must hold): the front (steps 1–2: x,
// analysis and envelope states, analysis_sum_sq, in_sum_sq; the envelopes
// into `work`), then the back (steps 3–4: carrier, work, prefilter and
// refilter states, the rest). The front of one block and the back of an
// earlier one touch nothing in common but their own `work`, so they can run
// on two threads at once; each alone gives what run_fused gives.
// Chunks are independent but for the replay's sum, which adds them in
// order: a range may run on another thread once the ranges before it have
// run over the same frames.
void run_fused(const FusedBanks& banks, const FusedBlock& block);
void run_fused_front(const FusedBanks& banks, const FusedBlock& block);
void run_fused_back(const FusedBanks& banks, const FusedBlock& block);

// Noise carriers for lanes [0, lanes) of a bank: at absolute frame t,
// lane l gets (bits · 2^-31 − 1) with bits the low (t even) or high (t odd)
// 32 bits of stream l's draw for t − t mod 2, which is drawn at even t.
// `state` holds xoshiro256** states [chunk][word][4], `draw` the last draw
// per lane (the bank's stride); padding lanes get 0.
// Only the chunks [chunk_begin, chunk_end) are made, into rows of
// `out_stride` whose column 0 is lane 0 of chunk_begin.
void noise_carriers(std::uint64_t* state, std::uint64_t* draw, std::size_t lanes, std::size_t chunk_begin,
                    std::size_t chunk_end, std::size_t out_stride, std::size_t first, std::size_t frames,
                    double* carrier);

}  // namespace avsi::vocoder::detail
