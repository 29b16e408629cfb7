// The analytic signal and Hilbert envelope by FFT (Marple 1999, "Computing
// the discrete-time analytic signal via FFT", IEEE Trans. Signal Process.
// 47(9)): zero the negative frequencies, double the positive ones. The
// signal is zero-padded to an FFT-friendly length (2^a·3^b·5^c).
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace avsi::vocoder {

// The analytic signal x + j·H{x}, same length as `signal`.
std::vector<std::complex<double>> analytic_signal(std::span<const double> signal);

// |x + j·H{x}|, the Hilbert envelope, same length as `signal`.
std::vector<double> hilbert_envelope(std::span<const double> signal);

// The smallest n' >= n whose only prime factors are 2, 3 and 5.
std::size_t fast_fft_size(std::size_t n);

}  // namespace avsi::vocoder
