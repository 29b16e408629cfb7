// Analytic signal by FFT (Marple 1999) with Eigen's FFT module.
#include "avsi/vocoder/hilbert.h"

#include <unsupported/Eigen/FFT>

namespace avsi::vocoder {

std::size_t fast_fft_size(std::size_t n) {
    if (n <= 1) return 1;
    for (std::size_t m = n;; ++m) {
        std::size_t r = m;
        for (std::size_t p : {2, 3, 5})
            while (r % p == 0) r /= p;
        if (r == 1) return m;
    }
}

std::vector<std::complex<double>> analytic_signal(std::span<const double> signal) {
    const std::size_t n = signal.size();
    if (n == 0) return {};
    const std::size_t m = fast_fft_size(n);
    std::vector<double> padded(m, 0.0);
    std::copy(signal.begin(), signal.end(), padded.begin());
    Eigen::FFT<double> fft;
    std::vector<std::complex<double>> spectrum;
    fft.fwd(spectrum, padded);
    // Keep DC (and Nyquist for even m), double the positive frequencies,
    // zero the negative ones.
    const std::size_t half = m / 2;
    for (std::size_t k = 1; k < m; ++k) {
        if (k < (m + 1) / 2)
            spectrum[k] *= 2.0;
        else if (!(m % 2 == 0 && k == half))
            spectrum[k] = 0.0;
    }
    std::vector<std::complex<double>> analytic;
    fft.inv(analytic, spectrum);
    analytic.resize(n);
    return analytic;
}

std::vector<double> hilbert_envelope(std::span<const double> signal) {
    const auto analytic = analytic_signal(signal);
    std::vector<double> envelope(analytic.size());
    for (std::size_t i = 0; i < analytic.size(); ++i) envelope[i] = std::abs(analytic[i]);
    return envelope;
}

}  // namespace avsi::vocoder
