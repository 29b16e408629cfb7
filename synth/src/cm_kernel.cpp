// The bounded Cohen-Massaro sum's inner loops (cm_kernel.h): |τ − t|^c as
// exp(c·ln|τ − t|) and D = exp(−rate·|τ − t|^c) accumulated into the
// numerator and denominator of eq. 8, vectorised with glibc's libmvec.
// The AVX2 variants are compiled for that target only inside the
// `#pragma GCC target` region and use nothing but intrinsics and libmvec
// (no inline library code that could be shared with the SSE2 build).
// AVSI_CM_KERNEL=sse2 or =scalar in the environment forces a narrower one.
#include "cm_kernel.h"

#include <cmath>
#include <cstdlib>
#include <cstring>

#if defined(__x86_64__) && defined(__GLIBC__)
#define AVSI_CM_LIBMVEC 1
#include <immintrin.h>
#endif

namespace avsi::synth::detail {

namespace {

// Plain C++ fallbacks (and the reference for the vector versions).
[[maybe_unused]] void power_scalar(double* u, std::size_t len, double c) {
    for (std::size_t f = 0; f < len; ++f) u[f] = u[f] > 0.0 ? std::exp(c * std::log(u[f])) : 0.0;
}

[[maybe_unused]] void accumulate_scalar(const double* u, std::size_t len, double rate, int count,
                                        const double* scale_num, const double* scale_den, double* const* num,
                                        double* const* den) {
    for (std::size_t f = 0; f < len; ++f) {
        const double e = std::exp(-rate * u[f]);
        for (int k = 0; k < count; ++k) {
            num[k][f] += scale_num[k] * e;
            den[k][f] += scale_den[k] * e;
        }
    }
}

[[maybe_unused]] void decay_sum_scalar(double* num, double* den, const double* decay, std::size_t rows,
                                       std::size_t width, bool decay_first, double* acc_num, double* acc_den) {
    for (std::size_t c = 0; c < width; ++c) acc_num[c] = acc_den[c] = 0.0;
    for (std::size_t r = 0; r < rows; ++r) {
        double* sn = num + r * width;
        double* sd = den + r * width;
        const double* d = decay + r * width;
        for (std::size_t c = 0; c < width; ++c) {
            if (decay_first) {
                sn[c] *= d[c];
                sd[c] *= d[c];
            }
            acc_num[c] += sn[c];
            acc_den[c] += sd[c];
        }
    }
}

[[maybe_unused]] void exp_scalar(double* v, std::size_t len) {
    for (std::size_t f = 0; f < len; ++f) v[f] = std::exp(v[f]);
}

}  // namespace

#ifdef AVSI_CM_LIBMVEC

// glibc's vector math (x86_64 vector function ABI names).
extern "C" __m128d _ZGVbN2v_exp(__m128d);
extern "C" __m128d _ZGVbN2v_log(__m128d);

namespace {

// SSE2: 2 doubles at a time; the last odd frame padded.
void power_sse2(double* u, std::size_t len, double c) {
    const __m128d vc = _mm_set1_pd(c);
    std::size_t f = 0;
    for (; f + 2 <= len; f += 2)
        _mm_storeu_pd(u + f, _ZGVbN2v_exp(_mm_mul_pd(vc, _ZGVbN2v_log(_mm_loadu_pd(u + f)))));
    if (f < len) u[f] = u[f] > 0.0 ? std::exp(c * std::log(u[f])) : 0.0;
}

void exp_sse2(double* v, std::size_t len) {
    std::size_t f = 0;
    for (; f + 2 <= len; f += 2) _mm_storeu_pd(v + f, _ZGVbN2v_exp(_mm_loadu_pd(v + f)));
    if (f < len) v[f] = std::exp(v[f]);
}

void decay_sum_sse2(double* num, double* den, const double* decay, std::size_t rows, std::size_t width,
                    bool decay_first, double* acc_num, double* acc_den) {
    if (width % 2 != 0) {
        decay_sum_scalar(num, den, decay, rows, width, decay_first, acc_num, acc_den);
        return;
    }
    for (std::size_t c = 0; c < width; c += 2) {
        __m128d an = _mm_setzero_pd(), ad = _mm_setzero_pd();
        for (std::size_t r = 0; r < rows; ++r) {
            const std::size_t o = r * width + c;
            __m128d sn = _mm_loadu_pd(num + o), sd = _mm_loadu_pd(den + o);
            if (decay_first) {
                const __m128d d = _mm_loadu_pd(decay + o);
                sn = _mm_mul_pd(sn, d);
                sd = _mm_mul_pd(sd, d);
                _mm_storeu_pd(num + o, sn);
                _mm_storeu_pd(den + o, sd);
            }
            an = _mm_add_pd(an, sn);
            ad = _mm_add_pd(ad, sd);
        }
        _mm_storeu_pd(acc_num + c, an);
        _mm_storeu_pd(acc_den + c, ad);
    }
}

void accumulate_sse2(const double* u, std::size_t len, double rate, int count, const double* scale_num,
                     const double* scale_den, double* const* num, double* const* den) {
    const __m128d neg_rate = _mm_set1_pd(-rate);
    std::size_t f = 0;
    for (; f + 2 <= len; f += 2) {
        const __m128d e = _ZGVbN2v_exp(_mm_mul_pd(neg_rate, _mm_loadu_pd(u + f)));
        for (int k = 0; k < count; ++k) {
            _mm_storeu_pd(num[k] + f, _mm_add_pd(_mm_loadu_pd(num[k] + f), _mm_mul_pd(_mm_set1_pd(scale_num[k]), e)));
            _mm_storeu_pd(den[k] + f, _mm_add_pd(_mm_loadu_pd(den[k] + f), _mm_mul_pd(_mm_set1_pd(scale_den[k]), e)));
        }
    }
    if (f < len) {
        const double e = std::exp(-rate * u[f]);
        for (int k = 0; k < count; ++k) {
            num[k][f] += scale_num[k] * e;
            den[k][f] += scale_den[k] * e;
        }
    }
}

}  // namespace

// (clang ignores GCC's target pragma: the same region as a function attribute.)
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2,fma"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2,fma")
#endif

extern "C" __m256d _ZGVdN4v_exp(__m256d);
extern "C" __m256d _ZGVdN4v_log(__m256d);

namespace {

// AVX2 + FMA: 4 doubles at a time; the last 1–3 frames padded (u = 1).
void power_avx2(double* u, std::size_t len, double c) {
    const __m256d vc = _mm256_set1_pd(c);
    std::size_t f = 0;
    for (; f + 4 <= len; f += 4)
        _mm256_storeu_pd(u + f, _ZGVdN4v_exp(_mm256_mul_pd(vc, _ZGVdN4v_log(_mm256_loadu_pd(u + f)))));
    if (f < len) {
        double pad[4] = {1.0, 1.0, 1.0, 1.0};
        for (std::size_t g = f; g < len; ++g) pad[g - f] = u[g];
        _mm256_storeu_pd(pad, _ZGVdN4v_exp(_mm256_mul_pd(vc, _ZGVdN4v_log(_mm256_loadu_pd(pad)))));
        for (std::size_t g = f; g < len; ++g) u[g] = pad[g - f];
    }
}

void exp_avx2(double* v, std::size_t len) {
    std::size_t f = 0;
    for (; f + 4 <= len; f += 4) _mm256_storeu_pd(v + f, _ZGVdN4v_exp(_mm256_loadu_pd(v + f)));
    if (f < len) {
        double pad[4] = {0.0, 0.0, 0.0, 0.0};
        for (std::size_t g = f; g < len; ++g) pad[g - f] = v[g];
        _mm256_storeu_pd(pad, _ZGVdN4v_exp(_mm256_loadu_pd(pad)));
        for (std::size_t g = f; g < len; ++g) v[g] = pad[g - f];
    }
}

void decay_sum_avx2(double* num, double* den, const double* decay, std::size_t rows, std::size_t width,
                    bool decay_first, double* acc_num, double* acc_den) {
    if (width % 4 != 0) {
        decay_sum_sse2(num, den, decay, rows, width, decay_first, acc_num, acc_den);
        return;
    }
    for (std::size_t c = 0; c < width; c += 4) {
        __m256d an = _mm256_setzero_pd(), ad = _mm256_setzero_pd();
        for (std::size_t r = 0; r < rows; ++r) {
            const std::size_t o = r * width + c;
            __m256d sn = _mm256_loadu_pd(num + o), sd = _mm256_loadu_pd(den + o);
            if (decay_first) {
                const __m256d d = _mm256_loadu_pd(decay + o);
                sn = _mm256_mul_pd(sn, d);
                sd = _mm256_mul_pd(sd, d);
                _mm256_storeu_pd(num + o, sn);
                _mm256_storeu_pd(den + o, sd);
            }
            an = _mm256_add_pd(an, sn);
            ad = _mm256_add_pd(ad, sd);
        }
        _mm256_storeu_pd(acc_num + c, an);
        _mm256_storeu_pd(acc_den + c, ad);
    }
}

void accumulate_avx2(const double* u, std::size_t len, double rate, int count, const double* scale_num,
                     const double* scale_den, double* const* num, double* const* den) {
    const __m256d neg_rate = _mm256_set1_pd(-rate);
    std::size_t f = 0;
    for (; f + 4 <= len; f += 4) {
        const __m256d e = _ZGVdN4v_exp(_mm256_mul_pd(neg_rate, _mm256_loadu_pd(u + f)));
        for (int k = 0; k < count; ++k) {
            _mm256_storeu_pd(num[k] + f, _mm256_fmadd_pd(_mm256_set1_pd(scale_num[k]), e, _mm256_loadu_pd(num[k] + f)));
            _mm256_storeu_pd(den[k] + f, _mm256_fmadd_pd(_mm256_set1_pd(scale_den[k]), e, _mm256_loadu_pd(den[k] + f)));
        }
    }
    if (f < len) {
        double pad[4] = {0.0, 0.0, 0.0, 0.0};
        for (std::size_t g = f; g < len; ++g) pad[g - f] = u[g];
        double e[4];
        _mm256_storeu_pd(e, _ZGVdN4v_exp(_mm256_mul_pd(neg_rate, _mm256_loadu_pd(pad))));
        for (int k = 0; k < count; ++k)
            for (std::size_t g = f; g < len; ++g) {
                num[k][g] += scale_num[k] * e[g - f];
                den[k][g] += scale_den[k] * e[g - f];
            }
    }
}

}  // namespace

#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

#endif  // AVSI_CM_LIBMVEC

namespace {

using PowerFn = void (*)(double*, std::size_t, double);
using ExpFn = void (*)(double*, std::size_t);
using AccumulateFn = void (*)(const double*, std::size_t, double, int, const double*, const double*, double* const*,
                              double* const*);
using DecaySumFn = void (*)(double*, double*, const double*, std::size_t, std::size_t, bool, double*, double*);

struct Kernels {
    PowerFn power;
    ExpFn exp;
    AccumulateFn accumulate;
    DecaySumFn decay_sum;
    const char* isa;
};

// AVSI_CM_KERNEL=sse2 or scalar picks a narrower variant (for checking
// each against the full sum and for timing them).
Kernels choose() {
    const char* forced = std::getenv("AVSI_CM_KERNEL");
    if (forced && std::strcmp(forced, "scalar") == 0)
        return {power_scalar, exp_scalar, accumulate_scalar, decay_sum_scalar, "scalar"};
#ifdef AVSI_CM_LIBMVEC
    __builtin_cpu_init();
    const bool narrow = forced && std::strcmp(forced, "sse2") == 0;
    if (!narrow && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        return {power_avx2, exp_avx2, accumulate_avx2, decay_sum_avx2, "avx2"};
    return {power_sse2, exp_sse2, accumulate_sse2, decay_sum_sse2, "sse2"};
#else
    return {power_scalar, exp_scalar, accumulate_scalar, decay_sum_scalar, "scalar"};
#endif
}

const Kernels& kernels() {
    static const Kernels k = choose();
    return k;
}

}  // namespace

void cm_power(double* u, std::size_t len, double c) { kernels().power(u, len, c); }

void cm_exp(double* v, std::size_t len) { kernels().exp(v, len); }

void cm_accumulate(const double* u, std::size_t len, double rate, int count, const double* scale_num,
                   const double* scale_den, double* const* num, double* const* den) {
    kernels().accumulate(u, len, rate, count, scale_num, scale_den, num, den);
}

void cm_decay_sum(double* num, double* den, const double* decay, std::size_t rows, std::size_t width,
                  bool decay_first, double* acc_num, double* acc_den) {
    kernels().decay_sum(num, den, decay, rows, width, decay_first, acc_num, acc_den);
}

const char* cm_kernel_isa() { return kernels().isa; }

}  // namespace avsi::synth::detail
