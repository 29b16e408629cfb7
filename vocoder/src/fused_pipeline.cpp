// The fused steps 1–4 and the vectorised noise carriers; see fused_pipeline.h.
// The per-lane arithmetic is written as in filters.cpp's run_chunk (BandPass
// and LowPass2 kernels) and the steps of channel_pipeline.cpp's plain way
// and reference.cpp, in the same order (but for one rewrite that gives the
// same value, see band_pass_section).
// Compiled without floating-point contraction (vocoder/CMakeLists.txt), so
// every clone below rounds alike.
#include "fused_pipeline.h"

#include <algorithm>
#include <cstring>

#include "avsi/core/error.h"

namespace avsi::vocoder::detail {

namespace {

constexpr std::size_t kChunk = SosBank::chunk_lanes;
constexpr std::size_t kBandSections = 4;      // Butterworth band-pass, order 4
constexpr std::size_t kEnvelopeSections = 2;  // Butterworth low-pass, order 4

typedef double Lanes __attribute__((vector_size(kChunk * sizeof(double))));
typedef std::uint64_t Words __attribute__((vector_size(kChunk * sizeof(std::uint64_t))));

[[gnu::always_inline]] inline void load(Lanes& v, const double* p) { std::memcpy(&v, p, sizeof v); }
[[gnu::always_inline]] inline void store(double* p, const Lanes& v) { std::memcpy(p, &v, sizeof v); }
[[gnu::always_inline]] inline void load(Words& v, const std::uint64_t* p) { std::memcpy(&v, p, sizeof v); }
[[gnu::always_inline]] inline void store(std::uint64_t* p, const Words& v) { std::memcpy(p, &v, sizeof v); }

// (Vectors by reference, never by value: that would depend on the ABI.)

// v = std::max(v, 0.0) per lane: v unless v < 0 (so -0 and NaN stay).
[[gnu::always_inline]] inline void max0(Lanes& v) {
    const Lanes zero = {0.0, 0.0, 0.0, 0.0};
    v = v < zero ? zero : v;
}

// v = std::abs(v) per lane: the sign bit cleared.
[[gnu::always_inline]] inline void abs(Lanes& v) {
    Words bits;
    std::memcpy(&bits, &v, sizeof bits);
    bits &= ~(Words{1, 1, 1, 1} << 63);
    std::memcpy(&v, &bits, sizeof v);
}

// A bank's coefficients and state for one chunk, in registers. `BandPass`:
// a2 is kept negated (see band_pass_section).
template <std::size_t Sections, bool BandPass>
struct Cascade {
    Lanes a1[Sections], a2[Sections], z1[Sections], z2[Sections], gain;
    double* z = nullptr;

    // (Loaded and stored through a temporary: the members' addresses are
    // never taken, so the compiler keeps them in registers.)
    void open(const SosBank& bank, SosBank::State& state, std::size_t chunk) {
        const double* c = bank.coefficients(chunk);
        z = state.z.data() + chunk * Sections * 2 * kChunk;
        Lanes t;
        for (std::size_t s = 0; s < Sections; ++s) {
            load(t, c + (s * 5 + 3) * kChunk);
            a1[s] = t;
            load(t, c + (s * 5 + 4) * kChunk);
            a2[s] = BandPass ? -t : t;
            load(t, z + (2 * s) * kChunk);
            z1[s] = t;
            load(t, z + (2 * s + 1) * kChunk);
            z2[s] = t;
        }
        load(t, bank.gain(chunk));
        gain = t;
    }
    void close() {
        for (std::size_t s = 0; s < Sections; ++s) {
            Lanes t = z1[s];
            store(z + (2 * s) * kChunk, t);
            t = z2[s];
            store(z + (2 * s + 1) * kChunk, t);
        }
    }
    // Section s of SosBank::Kind::BandPass (numerator b0·(1, 0, -1), b0 in
    // the gain) on v. z2 = −v − a2·y, as (−a2)·y − v: the same value in
    // every case (a product's sign is the operands' and x − y is x + (−y),
    // which commutes), one negation fewer a section.
    [[gnu::always_inline]] void band_pass_section(std::size_t s, Lanes& v) {
        static_assert(BandPass);
        const Lanes y = v + z1[s];
        z1[s] = z2[s] - a1[s] * y;
        z2[s] = a2[s] * y - v;
        v = y;
    }
    // Section s of SosBank::Kind::LowPass2 (numerator b0·(1, 2, 1)).
    [[gnu::always_inline]] void low_pass_section(std::size_t s, Lanes& v) {
        static_assert(!BandPass);
        const Lanes y = v + z1[s];
        z1[s] = ((v + v) + z2[s]) - a1[s] * y;
        z2[s] = v - a2[s] * y;
        v = y;
    }
};

// The row length of the block's `work` and `carrier`, and the column of a
// chunk's lane 0 in them.
inline std::size_t row_stride(const FusedBanks& banks, const FusedBlock& block) {
    return block.stride ? block.stride : banks.bands->stride();
}
inline std::size_t column(const FusedBlock& block, std::size_t chunk) {
    return (chunk - block.chunk_begin) * kChunk;
}

// Two loops over the block, each with the state of at most eight sections
// in registers: the front, steps 1–2 (analysis, rectification, envelope;
// the envelope into `work`), and the back, steps 3–4 (carrier, modulation,
// re-filter) and the rows. They share nothing but `work`, so the front of
// one block can run beside the back of the block before it (run_fused_front
// and run_fused_back, on two threads).
//
// Each loop is skewed: in step n, section k of the cascade works on frame
// n − k, on what section k − 1 gave in step n − 1. A section's recursion
// (its state from one frame to the next: a multiply, a subtract and an
// add) is then the longest chain through a step, and the sections of a
// step are independent of each other, so the core runs them side by side
// without looking ahead across frames (docs/performance.md has the
// measurement). Every section still sees its frames in order with the same
// inputs, so each value is the same bit for bit. The first and last steps of a block run only the sections
// whose frame is in the block (`Edge`), so the state is whole at the
// block's end.

// `Edge`: step n of a block of `frames`, where section k runs only when
// frame n − k is in the block.
template <bool Edge>
struct Step {
    std::size_t n, frames;
    [[gnu::always_inline]] bool runs(std::size_t k) const { return !Edge || (n >= k && n - k < frames); }
};

// Steps 0 .. frames + Last − 1 of a skewed loop whose last section is
// `Last`: those where every section runs without the checks.
template <std::size_t Last, typename Loop>
[[gnu::always_inline]] inline void run_steps(Loop& loop, std::size_t frames) {
    const std::size_t steps = frames + Last;
    std::size_t n = 0;
    for (; n < std::min(Last, steps); ++n) loop.step(Step<true>{n, frames});
    for (; n < frames; ++n) loop.step(Step<false>{n, frames});
    for (; n < steps; ++n) loop.step(Step<true>{n, frames});
}

template <bool FullWave>
struct Front {
    // Sections 0–3 the analysis band-pass, 4–5 the envelope low-pass.
    static_assert(kBandSections == 4 && kEnvelopeSections == 2);
    static constexpr std::size_t kLast = 5;  // frame n − 5 leaves step n
    Cascade<kBandSections, true> analysis;
    Cascade<kEnvelopeSections, false> envelope;
    // Zeroed: the skewed steps write u[k] before they read it (st.runs), which
    // GCC cannot prove (-Wmaybe-uninitialized under -Werror in CI).
    Lanes u[kLast]{};  // u[k]: what section k gave in the last step
    Lanes analysis_sq;
    double in_sq;
    bool input_energy;
    const double* x;
    double* work;
    std::size_t stride;

    template <bool Edge>
    [[gnu::always_inline]] void step(const Step<Edge>& st) {
        // The last section first, so that each reads u[k − 1] of the last step.
        if (st.runs(5)) {  // envelope low-pass, section 1, and the envelope out
            Lanes v = u[4];
            envelope.low_pass_section(1, v);
            v *= envelope.gain;
            store(work + (st.n - 5) * stride, v);
        }
        if (st.runs(4)) {  // envelope low-pass, section 0
            Lanes v = u[3];
            envelope.low_pass_section(0, v);
            u[4] = v;
        }
        if (st.runs(3)) {  // analysis, section 3; its energy; 2. rectification
            Lanes v = u[2];
            analysis.band_pass_section(3, v);
            v *= analysis.gain;
            analysis_sq += v * v;
            if constexpr (FullWave)
                abs(v);
            else
                max0(v);
            u[3] = v;
        }
        for (std::size_t k = 2; k >= 1; --k) {
            if (st.runs(k)) {
                Lanes v = u[k - 1];
                analysis.band_pass_section(k, v);
                u[k] = v;
            }
        }
        if (st.runs(0)) {  // 1. analysis, section 0, on the input
            const double xn = x[st.n];
            if (input_energy) in_sq += xn * xn;
            Lanes v = {xn, xn, xn, xn};
            analysis.band_pass_section(0, v);
            u[0] = v;
        }
    }
};

template <bool FullWave>
[[gnu::always_inline]] inline void front_chunk(const FusedBanks& banks, const FusedBlock& block, std::size_t chunk) {
    using F = Front<FullWave>;
    const std::size_t lane0 = chunk * kChunk;
    F f;
    f.stride = row_stride(banks, block);
    f.x = block.x;
    f.work = block.work + column(block, chunk);
    f.analysis.open(*banks.bands, *banks.analysis, chunk);
    f.envelope.open(*banks.envelope, *banks.envelope_state, chunk);
    load(f.analysis_sq, block.analysis_sum_sq + lane0);
    f.in_sq = block.in_sum_sq ? *block.in_sum_sq : 0.0;
    f.input_energy = block.in_sum_sq && chunk == 0;
    run_steps<F::kLast>(f, block.frames);
    if (f.input_energy) *block.in_sum_sq = f.in_sq;
    store(block.analysis_sum_sq + lane0, f.analysis_sq);
    f.analysis.close();
    f.envelope.close();
}

template <bool Prefilter, bool Refilter, bool Replay>
struct Back {
    // Sections: the prefilter's (on the carrier) are 0 .. P − 1; the product
    // of frame n − P is made in step n; the re-filter's section j is P + j.
    static constexpr std::size_t P = Prefilter ? kBandSections : 0;
    static constexpr std::size_t R = Refilter ? kBandSections : 0;
    static constexpr std::size_t kLast = P + (R ? R - 1 : 0);  // frame n − kLast leaves step n
    static_assert(kBandSections > 1);  // so the re-filter's section 0 is never its last
    Cascade<kBandSections, true> prefilter, refilter;
    Lanes pre[kBandSections]{};  // what prefilter section k gave in the last step (zeroed as u above)
    Lanes re[kBandSections];   // the same for the re-filter
    Lanes out_sq;
    bool out_energy;
    double g[kChunk] = {};  // the replay's gains
    const double* carrier;
    const double* work;
    std::size_t stride;
    const FusedBlock* block;
    float* rows;
    std::size_t row_lanes, valid;
    std::size_t chunk;

    // What leaves the back for frame m.
    [[gnu::always_inline]] void out(std::size_t m, const Lanes& v) {
        if constexpr (Replay) {
            double s = chunk == 0 ? 0.0 : block->sum[m];
            for (std::size_t j = 0; j < kChunk; ++j) s += g[j] * static_cast<float>(v[j]);
            block->sum[m] = s;
        } else {
            if (out_energy) out_sq += v * v;
            if (rows)
                for (std::size_t j = 0; j < valid; ++j) rows[m * row_lanes + j] = static_cast<float>(v[j]);
        }
    }

    template <bool Edge>
    [[gnu::always_inline]] void step(const Step<Edge>& st) {
        // Re-filter sections, the last first.
        if constexpr (R > 0) {
            for (std::size_t j = R - 1; j >= 1; --j) {
                if (st.runs(P + j)) {
                    Lanes v = re[j - 1];
                    refilter.band_pass_section(j, v);
                    if (j == R - 1) {
                        v *= refilter.gain;
                        out(st.n - (P + j), v);
                    } else {
                        re[j] = v;
                    }
                }
            }
        }
        // 4. The product of frame n − P (envelope floored at zero), and the
        // re-filter's first section on it.
        if (st.runs(P)) {
            const std::size_t m = st.n - P;
            Lanes c, v;
            if constexpr (P > 0) {
                c = pre[P - 1];
                c *= prefilter.gain;
            } else {
                load(c, carrier + m * stride);
            }
            load(v, work + m * stride);
            max0(v);
            v *= c;
            if constexpr (R > 0) {
                refilter.band_pass_section(0, v);
                re[0] = v;
            } else {
                out(m, v);
            }
        }
        // 3. The carrier through the prefilter, the last section first.
        if constexpr (P > 0) {
            for (std::size_t k = P - 1; k >= 1; --k) {
                if (st.runs(k)) {
                    Lanes c = pre[k - 1];
                    prefilter.band_pass_section(k, c);
                    pre[k] = c;
                }
            }
            if (st.runs(0)) {
                Lanes c;
                load(c, carrier + st.n * stride);
                prefilter.band_pass_section(0, c);
                pre[0] = c;
            }
        }
    }
};

template <bool Prefilter, bool Refilter, bool Replay>
[[gnu::always_inline]] inline void back_chunk(const FusedBanks& banks, const FusedBlock& block, std::size_t chunk) {
    using B = Back<Prefilter, Refilter, Replay>;
    const std::size_t lane0 = chunk * kChunk;
    B b;
    b.stride = row_stride(banks, block);
    b.carrier = block.carrier + column(block, chunk);
    b.work = block.work + column(block, chunk);
    b.block = &block;
    b.chunk = chunk;
    if constexpr (Prefilter) b.prefilter.open(*banks.bands, *banks.prefilter, chunk);
    if constexpr (Refilter) b.refilter.open(*banks.bands, *banks.refilter, chunk);
    b.out_sq = Lanes{0, 0, 0, 0};
    b.out_energy = !Replay && block.out_sum_sq;
    if (b.out_energy) load(b.out_sq, block.out_sum_sq + lane0);
    if constexpr (Replay)
        for (std::size_t j = 0; j < kChunk; ++j) b.g[j] = block.gains[lane0 + j];
    b.rows = block.rows ? block.rows + lane0 : nullptr;
    b.row_lanes = block.lanes;
    b.valid = block.lanes > lane0 ? std::min(kChunk, block.lanes - lane0) : 0;
    run_steps<B::kLast>(b, block.frames);
    if (b.out_energy) store(block.out_sum_sq + lane0, b.out_sq);
    if constexpr (Prefilter) b.prefilter.close();
    if constexpr (Refilter) b.refilter.close();
}

template <bool Prefilter, bool Refilter>
[[gnu::always_inline]] inline void back_chunk_squares(const FusedBanks& banks, const FusedBlock& block,
                                                      std::size_t chunk) {
    if (block.sum)
        back_chunk<Prefilter, Refilter, true>(banks, block, chunk);
    else
        back_chunk<Prefilter, Refilter, false>(banks, block, chunk);
}

// AVX-512 (32 vector registers), AVX2, and the baseline, picked at load time.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void front_dispatch(
    const FusedBanks& banks, const FusedBlock& block, std::size_t chunk) {
    if (banks.full_wave)
        front_chunk<true>(banks, block, chunk);
    else
        front_chunk<false>(banks, block, chunk);
}

__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void back_dispatch(
    const FusedBanks& banks, const FusedBlock& block, std::size_t chunk) {
    const bool pre = banks.prefilter != nullptr, re = banks.refilter != nullptr;
    if (pre && re) return back_chunk_squares<true, true>(banks, block, chunk);
    if (pre) return back_chunk_squares<true, false>(banks, block, chunk);
    if (re) return back_chunk_squares<false, true>(banks, block, chunk);
    return back_chunk_squares<false, false>(banks, block, chunk);
}

// x = rotl(x, k) per lane.
[[gnu::always_inline]] inline void rotl(Words& x, int k) { x = (x << k) | (x >> (64 - k)); }

// `valid`: the chunk's lanes that are bands (the rest get 0).
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void noise_chunk(std::uint64_t* state, std::uint64_t* draw,
                                                                     std::size_t valid, std::size_t stride,
                                                                     std::size_t first, std::size_t frames,
                                                                     double* carrier) {
    Words s0, s1, s2, s3, d;
    load(s0, state);
    load(s1, state + kChunk);
    load(s2, state + 2 * kChunk);
    load(s3, state + 3 * kChunk);
    load(d, draw);
    const Words exponent = {0x4330000000000000, 0x4330000000000000, 0x4330000000000000, 0x4330000000000000};
    const Words low = {0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff};
    const Lanes two52 = {0x1p52, 0x1p52, 0x1p52, 0x1p52};
    const Lanes scale = {0x1p-31, 0x1p-31, 0x1p-31, 0x1p-31};
    const Lanes one = {1.0, 1.0, 1.0, 1.0};
    Words keep;
    for (std::size_t l = 0; l < kChunk; ++l) keep[l] = l < valid ? ~std::uint64_t{0} : 0;
    for (std::size_t n = 0; n < frames; ++n) {
        const std::size_t t = first + n;
        if (t % 2 == 0) {
            // xoshiro256** (Rng::next_u64), four streams at once; ·5 and ·9 as shifts and adds.
            Words r = (s1 << 2) + s1;
            rotl(r, 7);
            d = (r << 3) + r;
            const Words shifted = s1 << 17;
            s2 ^= s0;
            s3 ^= s1;
            s1 ^= s2;
            s0 ^= s3;
            s2 ^= shifted;
            rotl(s3, 45);
        }
        const Words bits = t % 2 == 0 ? (d & low) : (d >> 32);
        // The 32-bit value as a double, exactly: 2^52 + bits − 2^52.
        const Words biased = bits | exponent;
        Lanes value;
        std::memcpy(&value, &biased, sizeof value);
        value = (value - two52) * scale - one;
        Words result;
        std::memcpy(&result, &value, sizeof result);
        result &= keep;
        std::memcpy(&value, &result, sizeof value);
        store(carrier + n * stride, value);
    }
    store(state, s0);
    store(state + kChunk, s1);
    store(state + 2 * kChunk, s2);
    store(state + 3 * kChunk, s3);
    store(draw, d);
}

}  // namespace

bool fused_supported(const SosBank& bands, const SosBank& envelope) {
    return bands.kind() == SosBank::Kind::BandPass && bands.sections() == kBandSections &&
           envelope.kind() == SosBank::Kind::LowPass2 && envelope.sections() == kEnvelopeSections &&
           envelope.stride() == bands.stride();
}

void run_fused_front(const FusedBanks& banks, const FusedBlock& block) {
    AVSI_ASSERT(fused_supported(*banks.bands, *banks.envelope));
    const std::size_t end = std::min(block.chunk_end, banks.bands->stride() / kChunk);
    for (std::size_t chunk = block.chunk_begin; chunk < end; ++chunk) front_dispatch(banks, block, chunk);
}

void run_fused_back(const FusedBanks& banks, const FusedBlock& block) {
    AVSI_ASSERT(fused_supported(*banks.bands, *banks.envelope));
    const std::size_t end = std::min(block.chunk_end, banks.bands->stride() / kChunk);
    for (std::size_t chunk = block.chunk_begin; chunk < end; ++chunk) back_dispatch(banks, block, chunk);
}

void run_fused(const FusedBanks& banks, const FusedBlock& block) {
    run_fused_front(banks, block);
    run_fused_back(banks, block);
}

void noise_carriers(std::uint64_t* state, std::uint64_t* draw, std::size_t lanes, std::size_t chunk_begin,
                    std::size_t chunk_end, std::size_t out_stride, std::size_t first, std::size_t frames,
                    double* carrier) {
    for (std::size_t chunk = chunk_begin; chunk < chunk_end; ++chunk)
        noise_chunk(state + chunk * 4 * kChunk, draw + chunk * kChunk, std::min(kChunk, lanes - chunk * kChunk),
                    out_stride, first, frames, carrier + (chunk - chunk_begin) * kChunk);
}

}  // namespace avsi::vocoder::detail
