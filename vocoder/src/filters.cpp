// Butterworth SOS design by analog prototype + bilinear transform, and the
// filter loops. See filters.h for the references.
#include "avsi/vocoder/filters.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "avsi/core/error.h"

namespace avsi::vocoder {

namespace {

using Complex = std::complex<double>;
// Poles of the normalised analog Butterworth low-pass prototype (cutoff
// 1 rad/s), in the left half plane: p_k = exp(jπ(2k + N + 1) / (2N)).
std::vector<Complex> prototype_poles(int order) {
    std::vector<Complex> poles;
    for (int k = 0; k < order; ++k)
        poles.push_back(std::polar(1.0, std::numbers::pi * (2.0 * k + order + 1) / (2.0 * order)));
    return poles;
}

// Bilinear transform of one analog pole: z = (2fs + s) / (2fs - s).
Complex bilinear(Complex s, double fs) { return (2.0 * fs + s) / (2.0 * fs - s); }

// Analog frequency (rad/s) that the bilinear transform maps onto f_hz.
double prewarp(double f_hz, double fs) { return 2.0 * fs * std::tan(std::numbers::pi * f_hz / fs); }

// Groups digital poles into sections: each pole with positive imaginary
// part with its conjugate, real poles two by two (one left over becomes a
// first-order section). Numerators are filled in by the caller.
Sos sections_from_poles(const std::vector<Complex>& poles) {
    Sos sos;
    std::vector<double> real_poles;
    for (const Complex& p : poles) {
        if (std::abs(p.imag()) < 1e-12 * std::max(1.0, std::abs(p))) {
            real_poles.push_back(p.real());
        } else if (p.imag() > 0) {
            Biquad q;
            q.a1 = -2.0 * p.real();
            q.a2 = std::norm(p);
            sos.push_back(q);
        }
    }
    std::sort(real_poles.begin(), real_poles.end());
    for (std::size_t i = 0; i < real_poles.size(); i += 2) {
        Biquad q;
        if (i + 1 < real_poles.size()) {
            q.a1 = -(real_poles[i] + real_poles[i + 1]);
            q.a2 = real_poles[i] * real_poles[i + 1];
        } else {
            q.a1 = -real_poles[i];
            q.a2 = 0.0;
        }
        sos.push_back(q);
    }
    return sos;
}

Complex section_response(const Biquad& q, Complex z_inv) {
    return (q.b0 + z_inv * (q.b1 + z_inv * q.b2)) / (1.0 + z_inv * (q.a1 + z_inv * q.a2));
}

// Scales a section's numerator so that |H(e^{jω})| = 1 at `omega`.
void normalise_at(Biquad& q, double omega) {
    const double g = std::abs(section_response(q, std::polar(1.0, -omega)));
    q.b0 /= g;
    q.b1 /= g;
    q.b2 /= g;
}

// One direct-form-II-transposed pass over a strided signal.
template <typename Index>
void run_sections(const Sos& sos, std::span<double> x, Index order) {
    for (const Biquad& q : sos) {
        double z1 = 0.0, z2 = 0.0;
        for (std::size_t i = 0; i < x.size(); ++i) {
            double& v = x[order(i)];
            const double in = v;
            const double y = q.b0 * in + z1;
            z1 = q.b1 * in - q.a1 * y + z2;
            z2 = q.b2 * in - q.a2 * y;
            v = y;
        }
    }
}

}  // namespace

Sos butterworth_lowpass(int order, double cutoff_hz, double sample_rate_hz) {
    AVSI_ASSERT(order >= 1);
    AVSI_ASSERT(cutoff_hz > 0.0 && cutoff_hz < sample_rate_hz / 2.0);
    const double wc = prewarp(cutoff_hz, sample_rate_hz);
    std::vector<Complex> poles;
    for (const Complex& p : prototype_poles(order)) poles.push_back(bilinear(p * wc, sample_rate_hz));
    Sos sos = sections_from_poles(poles);
    // All zeros at s = ∞, i.e. z = -1: (1 + z^-1)^2 per pair, (1 + z^-1) alone.
    for (Biquad& q : sos) {
        const bool first_order = q.a2 == 0.0;
        q.b0 = 1.0;
        q.b1 = first_order ? 1.0 : 2.0;
        q.b2 = first_order ? 0.0 : 1.0;
        normalise_at(q, 0.0);
    }
    return sos;
}

Sos butterworth_bandpass(int order, double low_hz, double high_hz, double sample_rate_hz) {
    AVSI_ASSERT(order >= 1);
    AVSI_ASSERT(low_hz > 0.0 && low_hz < high_hz && high_hz < sample_rate_hz / 2.0);
    const double fs = sample_rate_hz;
    const double wl = prewarp(low_hz, fs);
    const double wh = prewarp(high_hz, fs);
    const double w0 = std::sqrt(wl * wh);
    const double bw = wh - wl;
    // Low-pass to band-pass, s -> (s² + w0²) / (bw·s): each prototype pole p
    // gives the two roots of s² - p·bw·s + w0² = 0.
    std::vector<Complex> poles;
    for (const Complex& p : prototype_poles(order)) {
        const Complex half = p * bw / 2.0;
        const Complex root = std::sqrt(half * half - w0 * w0);
        poles.push_back(bilinear(half + root, fs));
        poles.push_back(bilinear(half - root, fs));
    }
    Sos sos = sections_from_poles(poles);
    AVSI_ASSERT(sos.size() == static_cast<std::size_t>(order));
    // `order` zeros at s = 0 (z = 1) and `order` at s = ∞ (z = -1): one of
    // each per section, (1 - z^-2). Each section gets unity gain at the
    // digital image of the analog centre w0, where the whole cascade has
    // unity gain, so the product is unity there too.
    const double omega0 = 2.0 * std::atan(w0 / (2.0 * fs));
    for (Biquad& q : sos) {
        q.b0 = 1.0;
        q.b1 = 0.0;
        q.b2 = -1.0;
        normalise_at(q, omega0);
    }
    return sos;
}

std::complex<double> sos_response(const Sos& sos, double frequency_hz, double sample_rate_hz) {
    const Complex z_inv = std::polar(1.0, -2.0 * std::numbers::pi * frequency_hz / sample_rate_hz);
    Complex h = 1.0;
    for (const Biquad& q : sos) h *= section_response(q, z_inv);
    return h;
}

void sos_filter(const Sos& sos, std::span<double> signal) {
    run_sections(sos, signal, [](std::size_t i) { return i; });
}

void sos_filtfilt(const Sos& sos, std::span<double> signal) {
    const std::size_t n = signal.size();
    run_sections(sos, signal, [](std::size_t i) { return i; });
    run_sections(sos, signal, [n](std::size_t i) { return n - 1 - i; });
}

// ---------------------------------------------------------------- SosBank

namespace {

constexpr std::size_t kChunk = 4;  // lanes per vector; one AVX or two SSE2 registers
constexpr std::size_t kCoefficients = 5;

// Four doubles handled as one value (GCC/Clang vector extension); the
// compiler maps it onto whatever vector registers the target has.
typedef double Lanes __attribute__((vector_size(kChunk * sizeof(double))));

// (By reference: passing vector types by value would depend on the ABI.)
[[gnu::always_inline]] inline void load(Lanes& v, const double* p) { std::memcpy(&v, p, sizeof v); }

[[gnu::always_inline]] inline void store(double* p, const Lanes& v) { std::memcpy(p, &v, sizeof v); }

bool same(double a, double b) { return std::abs(a - b) <= 1e-14 * std::max(std::abs(a), std::abs(b)); }

// One chunk of four lanes through the cascade. The section kernels are
// direct form II transposed; for BandPass the numerator is b0·(1, 0, -1)
// and for LowPass2 b0·(1, 2, 1), with b0 multiplied in once at the end.
// Fixed > 0: the section count known at compile time, so the loops unroll
// and the filter state stays in registers; 0: `sections` at run time.
template <SosBank::Kind K, std::size_t Fixed>
[[gnu::always_inline]] inline void run_chunk(const double* coefficients, const double* gain, std::size_t runtime_sections, double* data,
               std::size_t stride, std::size_t frames, bool backward, double* z) {
    const std::size_t sections = Fixed > 0 ? Fixed : runtime_sections;
    Lanes b0[SosBank::max_sections], b1[SosBank::max_sections], b2[SosBank::max_sections];
    Lanes a1[SosBank::max_sections], a2[SosBank::max_sections];
    Lanes z1[SosBank::max_sections], z2[SosBank::max_sections];
    for (std::size_t s = 0; s < sections; ++s) {
        const double* c = coefficients + s * kCoefficients * kChunk;
        load(b0[s], c);
        load(b1[s], c + kChunk);
        load(b2[s], c + 2 * kChunk);
        load(a1[s], c + 3 * kChunk);
        load(a2[s], c + 4 * kChunk);
        load(z1[s], z + (2 * s) * kChunk);
        load(z2[s], z + (2 * s + 1) * kChunk);
    }
    Lanes g;
    load(g, gain);
    for (std::size_t step = 0; step < frames; ++step) {
        double* row = data + (backward ? frames - 1 - step : step) * stride;
        Lanes v;
        load(v, row);
        for (std::size_t s = 0; s < sections; ++s) {
            if constexpr (K == SosBank::Kind::BandPass) {
                const Lanes y = v + z1[s];
                z1[s] = z2[s] - a1[s] * y;
                z2[s] = -v - a2[s] * y;
                v = y;
            } else if constexpr (K == SosBank::Kind::LowPass2) {
                const Lanes y = v + z1[s];
                z1[s] = ((v + v) + z2[s]) - a1[s] * y;  // y last: shortest loop-carried chain
                z2[s] = v - a2[s] * y;
                v = y;
            } else {
                const Lanes y = b0[s] * v + z1[s];
                z1[s] = b1[s] * v - a1[s] * y + z2[s];
                z2[s] = b2[s] * v - a2[s] * y;
                v = y;
            }
        }
        if constexpr (K != SosBank::Kind::Generic) v *= g;
        store(row, v);
    }
    for (std::size_t s = 0; s < sections; ++s) {
        store(z + (2 * s) * kChunk, z1[s]);
        store(z + (2 * s + 1) * kChunk, z2[s]);
    }
}

}  // namespace

SosBank::SosBank(const std::vector<Sos>& cascades) {
    AVSI_ASSERT(!cascades.empty());
    m_lanes = cascades.size();
    m_sections = cascades.front().size();
    AVSI_ASSERT(m_sections >= 1 && m_sections <= max_sections);
    m_stride = (m_lanes + kChunk - 1) / kChunk * kChunk;
    bool band_pass = true, low_pass2 = true;
    for (const Sos& sos : cascades) {
        AVSI_ASSERT(sos.size() == m_sections);
        for (const Biquad& q : sos) {
            band_pass &= q.b1 == 0.0 && same(q.b2, -q.b0);
            low_pass2 &= same(q.b1, 2.0 * q.b0) && same(q.b2, q.b0);
        }
    }
    m_kind = band_pass ? Kind::BandPass : low_pass2 ? Kind::LowPass2 : Kind::Generic;
    // Padding lanes get an all-zero numerator and output: b0 = 0, gain 0.
    m_coefficients.assign(m_stride / kChunk * m_sections * kCoefficients * kChunk, 0.0);
    m_gain.assign(m_stride, 0.0);
    for (std::size_t l = 0; l < m_lanes; ++l) {
        const std::size_t chunk = l / kChunk, j = l % kChunk;
        double gain = 1.0;
        for (std::size_t s = 0; s < m_sections; ++s) {
            const Biquad& q = cascades[l][s];
            double* c = &m_coefficients[((chunk * m_sections + s) * kCoefficients) * kChunk + j];
            const double values[kCoefficients] = {q.b0, q.b1, q.b2, q.a1, q.a2};
            for (std::size_t k = 0; k < kCoefficients; ++k) c[k * kChunk] = values[k];
            gain *= q.b0;
        }
        m_gain[l] = gain;
    }
}

SosBank::State SosBank::initial_state() const {
    return State{std::vector<double>(m_stride / kChunk * m_sections * 2 * kChunk, 0.0)};
}

namespace {

template <SosBank::Kind K>
[[gnu::always_inline]] inline void run_chunk_sections(const double* c, const double* g, std::size_t sections,
                                                      double* data, std::size_t stride, std::size_t frames,
                                                      bool backward, double* z) {
    switch (sections) {
        case 1: return run_chunk<K, 1>(c, g, sections, data, stride, frames, backward, z);
        case 2: return run_chunk<K, 2>(c, g, sections, data, stride, frames, backward, z);
        case 3: return run_chunk<K, 3>(c, g, sections, data, stride, frames, backward, z);
        case 4: return run_chunk<K, 4>(c, g, sections, data, stride, frames, backward, z);
        case 6: return run_chunk<K, 6>(c, g, sections, data, stride, frames, backward, z);
        case 8: return run_chunk<K, 8>(c, g, sections, data, stride, frames, backward, z);
        default: return run_chunk<K, 0>(c, g, sections, data, stride, frames, backward, z);
    }
}

// Built twice, for AVX2 and for the baseline, and picked at load time by
// the CPU (GCC function multi-versioning). Both run the same IEEE
// operations per lane (no FMA contraction), so their output is identical.
__attribute__((target_clones("avx2", "default"))) void run_chunk_dispatch(
    SosBank::Kind kind, const double* c, const double* g, std::size_t sections, double* data,
    std::size_t stride, std::size_t frames, bool backward, double* z) {
    switch (kind) {
        case SosBank::Kind::BandPass:
            return run_chunk_sections<SosBank::Kind::BandPass>(c, g, sections, data, stride, frames, backward, z);
        case SosBank::Kind::LowPass2:
            return run_chunk_sections<SosBank::Kind::LowPass2>(c, g, sections, data, stride, frames, backward, z);
        case SosBank::Kind::Generic:
            return run_chunk_sections<SosBank::Kind::Generic>(c, g, sections, data, stride, frames, backward, z);
    }
}

}  // namespace

void SosBank::run(double* data, std::size_t frames, bool backward, double* z) const {
    for (std::size_t chunk = 0; chunk < m_stride / kChunk; ++chunk) {
        const double* c = &m_coefficients[chunk * m_sections * kCoefficients * kChunk];
        const double* g = &m_gain[chunk * kChunk];
        double* zc = z + chunk * m_sections * 2 * kChunk;
        run_chunk_dispatch(m_kind, c, g, m_sections, data + chunk * kChunk, m_stride, frames, backward, zc);
    }
}

void SosBank::process(double* data, std::size_t frames, bool backward) const {
    State state = initial_state();
    run(data, frames, backward, state.z.data());
}

void SosBank::process(double* data, std::size_t frames, State& state) const {
    AVSI_ASSERT(state.z.size() == m_stride / kChunk * m_sections * 2 * kChunk);
    run(data, frames, false, state.z.data());
}

}  // namespace avsi::vocoder
