// STOI and ESTOI; see stoi.h. Step names follow the reference
// implementation (MATLAB stoi.m by C. Taal; pystoi by M. Pariente).
#include "avsi/vocoder/stoi.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>

#include <fmt/format.h>
#include <unsupported/Eigen/FFT>

#include "avsi/core/error.h"
#include "avsi/vocoder/resample.h"

namespace avsi::vocoder {

namespace {

constexpr double kRate = 10000.0;
constexpr std::size_t kFrame = 256;
constexpr std::size_t kHop = kFrame / 2;
constexpr std::size_t kFft = 512;
constexpr std::size_t kBands = 15;
constexpr double kMinFrequency = 150.0;
constexpr std::size_t kSegment = 30;  // N
constexpr double kBetaDb = -15.0;
constexpr double kDynamicRangeDb = 40.0;
constexpr double kEps = std::numeric_limits<double>::epsilon();

// Hann window of length `n` without its zero end points: hanning(n + 2)[1:-1].
std::vector<double> hann(std::size_t n) {
    std::vector<double> w(n);
    for (std::size_t i = 0; i < n; ++i)
        w[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i + 1) / static_cast<double>(n + 1));
    return w;
}

// Frame starts as the reference implementation takes them: range(0, len - frame, hop).
std::size_t frame_count(std::size_t length) {
    if (length <= kFrame) return 0;
    return (length - kFrame - 1) / kHop + 1;
}

// Drops the frames whose clean energy is more than 40 dB below the loudest
// clean frame, from both signals, and rebuilds each by overlap-add.
void remove_silent_frames(std::vector<double>& x, std::vector<double>& y) {
    const std::vector<double> w = hann(kFrame);
    const std::size_t frames = frame_count(x.size());
    std::vector<double> energy_db(frames);
    for (std::size_t f = 0; f < frames; ++f) {
        double sum = 0.0;
        for (std::size_t i = 0; i < kFrame; ++i) {
            const double v = w[i] * x[f * kHop + i];
            sum += v * v;
        }
        energy_db[f] = 20.0 * std::log10(std::sqrt(sum) + kEps);
    }
    const double loudest = frames ? *std::max_element(energy_db.begin(), energy_db.end()) : 0.0;
    std::vector<std::size_t> kept;
    for (std::size_t f = 0; f < frames; ++f)
        if (loudest - kDynamicRangeDb - energy_db[f] < 0.0) kept.push_back(f);
    const std::size_t length = kept.empty() ? 0 : (kept.size() - 1) * kHop + kFrame;
    std::vector<double> xs(length, 0.0), ys(length, 0.0);
    for (std::size_t k = 0; k < kept.size(); ++k)
        for (std::size_t i = 0; i < kFrame; ++i) {
            xs[k * kHop + i] += w[i] * x[kept[k] * kHop + i];
            ys[k * kHop + i] += w[i] * y[kept[k] * kHop + i];
        }
    x = std::move(xs);
    y = std::move(ys);
}

// One-third-octave band matrix over the 257 FFT bins: band j covers bins
// [lo_j, hi_j) with edges at the bins nearest 150·2^((2j∓1)/6) Hz.
std::vector<std::pair<std::size_t, std::size_t>> third_octave_bins() {
    const std::size_t bins = kFft / 2 + 1;
    std::vector<std::pair<std::size_t, std::size_t>> bands;
    auto nearest = [&](double f) {
        std::size_t best = 0;
        double best_d = INFINITY;
        for (std::size_t k = 0; k < bins; ++k) {
            const double d = std::pow(kRate * static_cast<double>(k) / kFft - f, 2.0);
            if (d < best_d) best_d = d, best = k;
        }
        return best;
    };
    for (std::size_t j = 0; j < kBands; ++j) {
        const double k = static_cast<double>(j);
        bands.emplace_back(nearest(kMinFrequency * std::pow(2.0, (2.0 * k - 1.0) / 6.0)),
                           nearest(kMinFrequency * std::pow(2.0, (2.0 * k + 1.0) / 6.0)));
    }
    return bands;
}

// Band envelopes: for each frame, the root of the summed power in each
// one-third-octave band. Result [frame][band].
std::vector<std::array<double, kBands>> band_envelopes(const std::vector<double>& x) {
    static const std::vector<double> w = hann(kFrame);
    static const auto bands = third_octave_bins();
    const std::size_t frames = frame_count(x.size());
    std::vector<std::array<double, kBands>> out(frames);
    Eigen::FFT<double> fft;
    std::vector<double> frame(kFft);
    std::vector<std::complex<double>> spectrum;
    for (std::size_t f = 0; f < frames; ++f) {
        std::fill(frame.begin(), frame.end(), 0.0);
        for (std::size_t i = 0; i < kFrame; ++i) frame[i] = w[i] * x[f * kHop + i];
        fft.fwd(spectrum, frame);
        for (std::size_t j = 0; j < kBands; ++j) {
            double power = 0.0;
            for (std::size_t k = bands[j].first; k < bands[j].second; ++k) power += std::norm(spectrum[k]);
            out[f][j] = std::sqrt(power);
        }
    }
    return out;
}

// Subtracts the mean of v[0..n) and scales it to unit norm (zero stays zero).
template <typename Get>
void normalise(std::size_t n, Get get) {
    double mean = 0.0;
    for (std::size_t i = 0; i < n; ++i) mean += get(i);
    mean /= static_cast<double>(n);
    double norm = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        get(i) -= mean;
        norm += get(i) * get(i);
    }
    norm = std::sqrt(norm);
    for (std::size_t i = 0; i < n; ++i) get(i) /= norm + kEps;
}

}  // namespace

double stoi(std::span<const double> clean, std::span<const double> degraded, double sample_rate_hz,
            const StoiSettings& settings) {
    if (clean.size() != degraded.size())
        throw InputError(Diagnostic{"", 0, 0, "stoi",
                                    fmt::format("expected clean and degraded signals of the same length, got {} "
                                                "and {} samples",
                                                clean.size(), degraded.size())});
    if (!(sample_rate_hz > 0.0))
        throw InputError(Diagnostic{"", 0, 0, "stoi", fmt::format("expected a positive sample rate, got {}", sample_rate_hz)});
    // 1. Resample to 10 kHz and remove silent frames.
    std::vector<double> x = resample(clean, sample_rate_hz, kRate);
    std::vector<double> y = resample(degraded, sample_rate_hz, kRate);
    remove_silent_frames(x, y);
    // 2. One-third-octave band envelopes per frame.
    const auto X = band_envelopes(x);
    const auto Y = band_envelopes(y);
    if (X.size() < kSegment)
        throw InputError(Diagnostic{
            "", 0, 0, "stoi",
            fmt::format("expected at least {} non-silent frames (about 0.4 s of speech at 10 kHz), got {}", kSegment,
                        X.size())});
    // 3. Intermediate intelligibility per 30-frame segment ending at frame m.
    const std::size_t segments = X.size() - kSegment + 1;
    const double clip = std::pow(10.0, -kBetaDb / 20.0);
    double total = 0.0;
    std::array<std::array<double, kSegment>, kBands> xs{}, ys{};
    for (std::size_t m = 0; m < segments; ++m) {
        for (std::size_t j = 0; j < kBands; ++j)
            for (std::size_t n = 0; n < kSegment; ++n) {
                xs[j][n] = X[m + n][j];
                ys[j][n] = Y[m + n][j];
            }
        if (settings.extended) {
            // ESTOI: normalise each band's row (mean, norm), then each
            // frame's column across bands; average the column correlations.
            for (std::size_t j = 0; j < kBands; ++j) {
                normalise(kSegment, [&](std::size_t n) -> double& { return xs[j][n]; });
                normalise(kSegment, [&](std::size_t n) -> double& { return ys[j][n]; });
            }
            for (std::size_t n = 0; n < kSegment; ++n) {
                normalise(kBands, [&](std::size_t j) -> double& { return xs[j][n]; });
                normalise(kBands, [&](std::size_t j) -> double& { return ys[j][n]; });
            }
            double d = 0.0;
            for (std::size_t j = 0; j < kBands; ++j)
                for (std::size_t n = 0; n < kSegment; ++n) d += xs[j][n] * ys[j][n];
            total += d / kSegment;
        } else {
            // STOI: scale the degraded row to the clean row's norm, clip at
            // (1 + 10^(-β/20)) times the clean envelope, correlate per band.
            for (std::size_t j = 0; j < kBands; ++j) {
                double nx = 0.0, ny = 0.0;
                for (std::size_t n = 0; n < kSegment; ++n) nx += xs[j][n] * xs[j][n], ny += ys[j][n] * ys[j][n];
                const double alpha = std::sqrt(nx) / (std::sqrt(ny) + kEps);
                for (std::size_t n = 0; n < kSegment; ++n) ys[j][n] = std::min(alpha * ys[j][n], xs[j][n] * (1.0 + clip));
                normalise(kSegment, [&](std::size_t n) -> double& { return xs[j][n]; });
                normalise(kSegment, [&](std::size_t n) -> double& { return ys[j][n]; });
                double d = 0.0;
                for (std::size_t n = 0; n < kSegment; ++n) d += xs[j][n] * ys[j][n];
                total += d / kBands;
            }
        }
    }
    // 4. The mean over segments (and bands).
    return total / static_cast<double>(segments);
}

double stoi(const Audio& clean, const Audio& degraded, const StoiSettings& settings) {
    if (clean.sample_rate_hz != degraded.sample_rate_hz)
        throw InputError(Diagnostic{"", 0, 0, "stoi",
                                    fmt::format("expected clean and degraded audio at the same sample rate, got "
                                                "{} Hz and {} Hz",
                                                clean.sample_rate_hz, degraded.sample_rate_hz)});
    const std::vector<float> a = clean.mono(), b = degraded.mono();
    const std::vector<double> x(a.begin(), a.end()), y(b.begin(), b.end());
    return stoi(x, y, clean.sample_rate_hz, settings);
}

std::vector<double> stoi_files(const std::filesystem::path& clean_path, const std::filesystem::path& degraded_path,
                               const StoiSettings& settings, ChannelMode channels) {
    const Audio clean = read_audio(clean_path), degraded = read_audio(degraded_path);
    const std::string c = clean_path.string(), d = degraded_path.string();
    if (clean.sample_rate_hz != degraded.sample_rate_hz)
        throw InputError(d, 0, 0, "sample rate",
                         fmt::format("expected the sample rate of {} ({} Hz), got {} Hz", c, clean.sample_rate_hz,
                                     degraded.sample_rate_hz));
    if (clean.frames() != degraded.frames())
        throw InputError(d, 0, 0, "length",
                         fmt::format("expected as many samples as {} ({}, {:.3f} s), got {} ({:.3f} s): STOI compares "
                                     "the signals frame by frame, so they must be aligned and of one length",
                                     c, clean.frames(), clean.duration_s(), degraded.frames(), degraded.duration_s()));
    if (channels == ChannelMode::Keep && clean.channels != degraded.channels)
        throw InputError(d, 0, 0, "channels",
                         fmt::format("expected the channel count of {} ({}) with --channels keep, got {}", c,
                                     clean.channels, degraded.channels));
    auto score = [&](const std::vector<float>& a, const std::vector<float>& b) {
        const std::vector<double> x(a.begin(), a.end()), y(b.begin(), b.end());
        try {
            return stoi(x, y, clean.sample_rate_hz, settings);
        } catch (const InputError& e) {
            std::vector<Diagnostic> diagnostics = e.diagnostics();
            for (Diagnostic& diag : diagnostics)
                if (diag.path.empty()) diag.path = d;
            throw InputError(std::move(diagnostics));
        }
    };
    std::vector<double> out;
    if (channels == ChannelMode::Keep) {
        for (int ch = 0; ch < clean.channels; ++ch) out.push_back(score(clean.channel(ch), degraded.channel(ch)));
    } else {
        out.push_back(score(mix_down(clean, c, "for STOI").samples, mix_down(degraded, d, "for STOI").samples));
    }
    return out;
}

}  // namespace avsi::vocoder
