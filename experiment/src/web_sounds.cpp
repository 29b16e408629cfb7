// The online study's generated sounds (see web_study.h): the antiphase
// headphone test's tones (Woods et al. 2017), Huggins-pitch noises (Milne et
// al. 2021; Cramer & Huggins 1958) and the calibration noise shaped like the
// stimuli. Noises are built in the frequency domain (Eigen's FFT): Gaussian
// complex bins give Gaussian noise, and an inverse FFT gives a signal that
// is periodic over its length, so a looped buffer has no click.
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <vector>

#include <unsupported/Eigen/FFT>

#include "avsi/core/rng.h"
#include "avsi/experiment/web_study.h"

namespace avsi::experiment {

namespace {

constexpr double antiphase_tone_hz = 200.0;  // Woods et al. 2017

double db_gain(double db) { return std::pow(10.0, db / 20.0); }

double rms(const std::vector<double>& x) {
    double sum = 0.0;
    for (double v : x) sum += v * v;
    return x.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(x.size()));
}

// Raised-cosine on and off ramps of `ramp` samples.
void apply_ramps(std::vector<double>& x, std::size_t ramp) {
    ramp = std::min(ramp, x.size() / 2);
    for (std::size_t i = 0; i < ramp; ++i) {
        const double g = 0.5 - 0.5 * std::cos(std::numbers::pi * (static_cast<double>(i) + 0.5) / static_cast<double>(ramp));
        x[i] *= g;
        x[x.size() - 1 - i] *= g;
    }
}

Audio stereo(const std::vector<double>& left, const std::vector<double>& right, int rate_hz) {
    Audio a;
    a.sample_rate_hz = rate_hz;
    a.channels = 2;
    a.samples.resize(left.size() * 2);
    for (std::size_t i = 0; i < left.size(); ++i) {
        a.samples[2 * i] = static_cast<float>(left[i]);
        a.samples[2 * i + 1] = static_cast<float>(right[i]);
    }
    return a;
}

// The real signal of a one-sided spectrum (bins 0..n/2) of length n.
std::vector<double> real_signal(std::vector<std::complex<double>> half, std::size_t n) {
    std::vector<std::complex<double>> full(n);
    for (std::size_t k = 0; k < half.size() && k < n; ++k) full[k] = half[k];
    for (std::size_t k = 1; k < (n + 1) / 2; ++k) full[n - k] = std::conj(full[k]);
    if (n % 2 == 0) full[n / 2] = std::complex<double>(full[n / 2].real(), 0.0);
    full[0] = std::complex<double>(full[0].real(), 0.0);
    Eigen::FFT<double> fft;
    std::vector<std::complex<double>> time;
    fft.inv(time, full);
    std::vector<double> out(n);
    for (std::size_t i = 0; i < n; ++i) out[i] = time[i].real();
    return out;
}

std::size_t samples_of(double ms, int rate_hz) { return static_cast<std::size_t>(std::lround(ms / 1000.0 * rate_hz)); }

}  // namespace

Audio antiphase_tone(const OnlineSettings& s, double level_dbfs, double gain_db, bool antiphase) {
    const std::size_t n = samples_of(s.tone_ms, s.sample_rate_hz);
    const double amplitude = std::sqrt(2.0) * db_gain(level_dbfs + gain_db);  // a sine's RMS is A/√2
    std::vector<double> left(n);
    for (std::size_t i = 0; i < n; ++i)
        left[i] = amplitude * std::sin(2.0 * std::numbers::pi * antiphase_tone_hz * static_cast<double>(i) / s.sample_rate_hz);
    apply_ramps(left, samples_of(s.ramp_ms, s.sample_rate_hz));
    std::vector<double> right = left;
    if (antiphase)
        for (double& v : right) v = -v;
    return stereo(left, right, s.sample_rate_hz);
}

Audio huggins_noise(const OnlineSettings& s, double level_dbfs, bool pitch, std::uint64_t seed) {
    const std::size_t n = samples_of(s.huggins_ms, s.sample_rate_hz);
    Rng rng(seed);
    std::vector<std::complex<double>> spectrum(n / 2 + 1);
    for (std::size_t k = 1; k < spectrum.size(); ++k) spectrum[k] = {rng.normal(), rng.normal()};
    std::vector<double> left = real_signal(spectrum, n);
    if (pitch) {
        // Invert the phase of the band f0·(1 ± band) in the right ear only.
        const double lo = s.huggins_hz * (1.0 - s.huggins_band), hi = s.huggins_hz * (1.0 + s.huggins_band);
        for (std::size_t k = 0; k < spectrum.size(); ++k) {
            const double f = static_cast<double>(k) * s.sample_rate_hz / static_cast<double>(n);
            if (f >= lo && f <= hi) spectrum[k] = -spectrum[k];
        }
    }
    std::vector<double> right = pitch ? real_signal(spectrum, n) : left;
    const double gain = db_gain(level_dbfs) / rms(left);
    for (std::size_t i = 0; i < n; ++i) {
        left[i] *= gain;
        right[i] *= gain;
    }
    const std::size_t ramp = samples_of(s.ramp_ms, s.sample_rate_hz);
    apply_ramps(left, ramp);
    apply_ramps(right, ramp);
    return stereo(left, right, s.sample_rate_hz);
}

Audio shaped_noise(const std::vector<std::vector<float>>& speech, int speech_rate_hz, double level_dbfs,
                   double duration_s, std::uint64_t seed, int out_rate_hz) {
    // Welch estimate of the long-term average power spectrum over the active
    // frames (within 40 dB of each clip's loudest frame, so pauses do not count).
    constexpr std::size_t frame = 2048, hop = 1024;
    std::vector<double> window(frame);
    for (std::size_t i = 0; i < frame; ++i)
        window[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / frame);
    std::vector<double> power(frame / 2 + 1, 0.0);
    std::size_t frames = 0;
    Eigen::FFT<double> fft;
    for (const auto& clip : speech) {
        if (clip.size() < frame) continue;
        std::vector<double> energy;
        for (std::size_t start = 0; start + frame <= clip.size(); start += hop) {
            double e = 0.0;
            for (std::size_t i = 0; i < frame; ++i) e += static_cast<double>(clip[start + i]) * clip[start + i];
            energy.push_back(e);
        }
        const double loudest = *std::max_element(energy.begin(), energy.end());
        if (loudest <= 0.0) continue;
        std::vector<double> x(frame);
        std::vector<std::complex<double>> spectrum;
        for (std::size_t f = 0, start = 0; start + frame <= clip.size(); start += hop, ++f) {
            if (energy[f] < loudest * 1e-4) continue;  // 40 dB below the loudest frame
            for (std::size_t i = 0; i < frame; ++i) x[i] = clip[start + i] * window[i];
            fft.fwd(spectrum, x);
            for (std::size_t k = 0; k < power.size(); ++k) power[k] += std::norm(spectrum[k]);
            ++frames;
        }
    }
    if (frames == 0) throw std::invalid_argument("shaped_noise: no active speech frame in the clips");
    // Noise of the requested length whose bins follow the estimate (linear
    // interpolation between the Welch bins).
    const auto n = static_cast<std::size_t>(std::lround(duration_s * out_rate_hz));
    Rng rng(seed);
    std::vector<std::complex<double>> spectrum(n / 2 + 1);
    for (std::size_t k = 1; k < spectrum.size(); ++k) {
        // This bin's frequency as a (fractional) Welch bin; nothing above the speech's Nyquist.
        const double hz = static_cast<double>(k) * out_rate_hz / static_cast<double>(n);
        const double position = hz * frame / speech_rate_hz;
        const auto below = static_cast<std::size_t>(position);
        if (below + 1 >= power.size()) break;
        const double t = position - static_cast<double>(below);
        const double p = (1.0 - t) * power[below] + t * power[below + 1];
        const double magnitude = std::sqrt(p / static_cast<double>(frames));
        spectrum[k] = magnitude * std::complex<double>(rng.normal(), rng.normal());
    }
    std::vector<double> noise = real_signal(spectrum, n);
    const double gain = db_gain(level_dbfs) / rms(noise);
    for (double& v : noise) v *= gain;
    return stereo(noise, noise, out_rate_hz);
}

}  // namespace avsi::experiment
