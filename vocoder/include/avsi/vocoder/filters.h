// Butterworth filters as cascades of second-order sections (SOS), designed
// from the analog prototype and mapped by the bilinear transform with
// pre-warped edges (Oppenheim & Schafer, Discrete-Time Signal Processing,
// §7.1; the same design as MATLAB/scipy `butter(..., output='sos')`), and
// the loops that run them: one signal, or a bank of parallel filters
// ("lanes", e.g. one per vocoder band) over interleaved samples.
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace avsi::vocoder {

// One second-order section, H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
struct Biquad {
    double b0 = 1.0, b1 = 0.0, b2 = 0.0;
    double a1 = 0.0, a2 = 0.0;
};

// A cascade of second-order sections, applied first to last.
using Sos = std::vector<Biquad>;

// Butterworth low-pass of `order` poles (order/2 sections, rounded up), unity
// gain at DC, -3.01 dB at cutoff_hz. Requires 0 < cutoff_hz < rate/2.
Sos butterworth_lowpass(int order, double cutoff_hz, double sample_rate_hz);

// Butterworth band-pass from an `order`-pole low-pass prototype (2·order
// poles, `order` sections; skirts fall 6·order dB/octave), unity gain at the
// geometric centre, -3.01 dB at low_hz and high_hz.
// Requires 0 < low_hz < high_hz < rate/2.
Sos butterworth_bandpass(int order, double low_hz, double high_hz, double sample_rate_hz);

// The complex frequency response of a cascade at `frequency_hz`.
std::complex<double> sos_response(const Sos& sos, double frequency_hz, double sample_rate_hz);

// Filters `signal` in place through the cascade from zero initial state.
void sos_filter(const Sos& sos, std::span<double> signal);

// Zero-phase filtering: forward, then backward through the same cascade
// (squared magnitude response, no phase shift; zero state, no padding).
void sos_filtfilt(const Sos& sos, std::span<double> signal);

// A bank of `lanes` cascades with the same number of sections (at most 16),
// run together over interleaved samples (sample n of lane l at
// data[n * stride() + l]). Lanes run side by side four at a time in vector
// registers. Numerators of the Butterworth shapes designed above are
// recognised and run with their gain factored out (fewer multiplies).
class SosBank {
public:
    static constexpr std::size_t max_sections = 16;

    // The filter memory between calls, for processing a signal block by block.
    struct State {
        std::vector<double> z;  // [chunk][section][2][4]
    };

    // Every cascade must have the same number of sections.
    explicit SosBank(const std::vector<Sos>& cascades);

    std::size_t lanes() const { return m_lanes; }
    // Lanes padded to a multiple of 4; the layout's row length.
    std::size_t stride() const { return m_stride; }
    std::size_t sections() const { return m_sections; }

    // A zero initial state.
    State initial_state() const;

    // Filters `frames` rows of `data` (frames × stride) in place, from zero
    // state, forward or backward in time.
    void process(double* data, std::size_t frames, bool backward = false) const;

    // Filters the next `frames` rows forward in time, continuing from `state`
    // and leaving the state after the last row there. Processing a signal in
    // blocks gives bit-for-bit the same output as processing it whole.
    void process(double* data, std::size_t frames, State& state) const;

    enum class Kind { Generic, BandPass, LowPass2 };
    Kind kind() const { return m_kind; }

    // The layout run by the kernels, for kernels elsewhere that run a bank
    // inside a longer per-sample loop (the vocoder's fused pipeline):
    // coefficients [chunk][section][b0 b1 b2 a1 a2][4], the factored gains
    // [chunk][4]; State::z is [chunk][section][z1 z2][4].
    static constexpr std::size_t chunk_lanes = 4;
    const double* coefficients(std::size_t chunk) const {
        return m_coefficients.data() + chunk * m_sections * 5 * chunk_lanes;
    }
    const double* gain(std::size_t chunk) const { return m_gain.data() + chunk * chunk_lanes; }

private:
    void run(double* data, std::size_t frames, bool backward, double* z) const;

    std::size_t m_lanes = 0;
    std::size_t m_stride = 0;
    std::size_t m_sections = 0;
    Kind m_kind = Kind::Generic;
    // Coefficients [chunk][section][b0 b1 b2 a1 a2][4], and for the factored
    // kinds the per-lane product of the b0 gains, [chunk][4].
    std::vector<double> m_coefficients;
    std::vector<double> m_gain;
};

}  // namespace avsi::vocoder
