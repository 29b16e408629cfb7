// The inner loops of the bounded Cohen-Massaro sum (cm_bounded_sum.h,
// eq. 7–8): |τ − t|^c and the dominance-weighted accumulation of one rate's
// parameters over a run of frames. On x86-64 with glibc they use glibc's
// vector math library (libmvec: exp, log within 4 ulp), 4 doubles at a time
// with AVX2 and FMA where the processor has them (chosen once at run time;
// the binary itself needs only SSE2), else 2 at a time with SSE2; elsewhere
// plain std::exp / std::log. The environment variable AVSI_CM_KERNEL=sse2
// or =scalar forces a narrower variant (checks and timing).
#pragma once

#include <cstddef>

namespace avsi::synth::detail {

// u[f] = u[f]^c for every f < len (u >= 0; 0^c = 0; c > 0).
void cm_power(double* u, std::size_t len, double c);

// With e[f] = exp(−rate·u[f]) for f < len, for each k < count:
// num[k][f] += scale_num[k]·e[f] and den[k][f] += scale_den[k]·e[f].
void cm_accumulate(const double* u, std::size_t len, double rate, int count, const double* scale_num,
                   const double* scale_den, double* const* num, double* const* den);

// v[f] = exp(v[f]) for every f < len.
void cm_exp(double* v, std::size_t len);

// The per-frame step of the c = 1 recursions (cm_bounded_sum.h): states
// num, den of `rows` rows × `width` columns (row-major), decay likewise.
// If decay_first, num and den are multiplied elementwise by decay; then
// acc_num[c] = Σ_r num[r·width + c] and acc_den[c] likewise (c < width).
void cm_decay_sum(double* num, double* den, const double* decay, std::size_t rows, std::size_t width,
                  bool decay_first, double* acc_num, double* acc_den);

// The instruction set the kernels run with: "avx2", "sse2" or "scalar".
const char* cm_kernel_isa();

}  // namespace avsi::synth::detail
