// STOI and ESTOI; see stoi.h. Step names follow the reference
// implementation (MATLAB stoi.m by C. Taal; pystoi by M. Pariente).
#include "avsi/vocoder/stoi.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <memory>
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

// A mono signal from its start, block by block, as often as asked.
class MonoInput {
public:
    virtual ~MonoInput() = default;
    virtual std::size_t size() const = 0;
    virtual void rewind() = 0;
    // Up to n samples; 0 at the end.
    virtual std::size_t read(double* out, std::size_t n) = 0;
};

class SpanInput : public MonoInput {
public:
    explicit SpanInput(std::span<const double> x) : m_x(x) {}
    std::size_t size() const override { return m_x.size(); }
    void rewind() override { m_position = 0; }
    std::size_t read(double* out, std::size_t n) override {
        n = std::min(n, m_x.size() - m_position);
        std::copy_n(m_x.begin() + static_cast<std::ptrdiff_t>(m_position), n, out);
        m_position += n;
        return n;
    }

private:
    std::span<const double> m_x;
    std::size_t m_position = 0;
};

// A source's channels mixed to mono as Audio::mono mixes them.
class SourceInput : public MonoInput {
public:
    explicit SourceInput(AudioSource& source) : m_source(source) {}
    std::size_t size() const override { return m_source.frames(); }
    void rewind() override { m_source.seek(0); }
    std::size_t read(double* out, std::size_t n) override {
        const std::size_t channels = static_cast<std::size_t>(m_source.channels());
        m_block.resize(n * channels);
        n = m_source.read(m_block.data(), n);
        for (std::size_t i = 0; i < n; ++i) {
            if (channels == 1) {
                out[i] = m_block[i];
                continue;
            }
            float sum = 0.0f;
            for (std::size_t c = 0; c < channels; ++c) sum += m_block[i * channels + c];
            out[i] = sum / static_cast<float>(channels);
        }
        return n;
    }

private:
    AudioSource& m_source;
    std::vector<float> m_block;
};

// The input at 10 kHz (resample()'s samples), hop by hop.
class At10kHz {
public:
    At10kHz(MonoInput& input, double rate) : m_input(input), m_rate(rate) { rewind(); }
    std::size_t size() const { return m_resampler->output_frames(); }
    void rewind() {
        m_input.rewind();
        m_resampler = std::make_unique<StreamResampler>(m_rate, kRate, m_input.size());
        m_ready.clear();
        m_taken = 0;
    }
    // The next n samples (all there are: the caller counts by size()).
    const double* next(std::size_t n) {
        while (m_ready.size() - m_taken < n) {
            m_block.resize(8192);
            const std::size_t got = m_input.read(m_block.data(), m_block.size());
            AVSI_ASSERT(got > 0);
            if (m_taken > 0) {
                m_ready.erase(m_ready.begin(), m_ready.begin() + static_cast<std::ptrdiff_t>(m_taken));
                m_taken = 0;
            }
            m_resampler->feed(m_block.data(), got, m_ready);
        }
        const double* out = m_ready.data() + m_taken;
        m_taken += n;
        return out;
    }

private:
    MonoInput& m_input;
    double m_rate;
    std::unique_ptr<StreamResampler> m_resampler;
    std::vector<double> m_ready, m_block;
    std::size_t m_taken = 0;
};

using Envelope = std::array<double, kBands>;

// One frame's band envelopes: the root of the summed power in each
// one-third-octave band of the windowed, zero-padded frame.
class EnvelopeAnalyser {
public:
    EnvelopeAnalyser() : m_window(hann(kFrame)), m_bands(third_octave_bins()), m_frame(kFft, 0.0) {}
    Envelope operator()(const double* x) {
        std::fill(m_frame.begin(), m_frame.end(), 0.0);
        for (std::size_t i = 0; i < kFrame; ++i) m_frame[i] = m_window[i] * x[i];
        m_fft.fwd(m_spectrum, m_frame);
        Envelope out;
        for (std::size_t j = 0; j < kBands; ++j) {
            double power = 0.0;
            for (std::size_t k = m_bands[j].first; k < m_bands[j].second; ++k) power += std::norm(m_spectrum[k]);
            out[j] = std::sqrt(power);
        }
        return out;
    }

private:
    std::vector<double> m_window;
    std::vector<std::pair<std::size_t, std::size_t>> m_bands;
    Eigen::FFT<double> m_fft;
    std::vector<double> m_frame;
    std::vector<std::complex<double>> m_spectrum;
};

// ESTOI's d/N of the segment of kSegment envelope frames from frame m (frame
// m + n at ring index (m + n) % kSegment): each band's row normalised (mean,
// norm), then each frame's column across bands; the column correlations
// averaged.
double estoi_segment(const std::array<Envelope, kSegment>& X, const std::array<Envelope, kSegment>& Y, std::size_t m) {
    std::array<std::array<double, kSegment>, kBands> xs{}, ys{};
    for (std::size_t j = 0; j < kBands; ++j)
        for (std::size_t n = 0; n < kSegment; ++n) {
            xs[j][n] = X[(m + n) % kSegment][j];
            ys[j][n] = Y[(m + n) % kSegment][j];
        }
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
    return d / kSegment;
}

// STOI per the reference implementation, in passes over the two inputs:
// (1) the loudest clean frame; (2) silent frames dropped and the rest
// overlap-added, both signals at once, framed again for the band
// envelopes, and each 30-frame segment scored as its last frame arrives.
// Memory: a few frames and the 30-frame segment, whatever the length.
double stoi_of(MonoInput& clean_in, MonoInput& degraded_in, double rate, bool extended) {
    At10kHz x(clean_in, rate), y(degraded_in, rate);
    const std::vector<double> w = hann(kFrame);
    const std::size_t frames = frame_count(x.size());
    auto energy_db = [&](const double* frame) {
        double sum = 0.0;
        for (std::size_t i = 0; i < kFrame; ++i) {
            const double v = w[i] * frame[i];
            sum += v * v;
        }
        return 20.0 * std::log10(std::sqrt(sum) + kEps);
    };
    // 1. The loudest clean frame (frames of kFrame every kHop).
    std::vector<double> window(kFrame), window_y(kFrame);
    auto slide = [&](At10kHz& signal, std::vector<double>& buffer, std::size_t f) {
        if (f == 0) {
            std::copy_n(signal.next(kFrame), kFrame, buffer.begin());
        } else {
            std::copy(buffer.begin() + kHop, buffer.end(), buffer.begin());
            std::copy_n(signal.next(kHop), kHop, buffer.begin() + kHop);
        }
    };
    double loudest = 0.0;
    for (std::size_t f = 0; f < frames; ++f) {
        slide(x, window, f);
        loudest = f == 0 ? energy_db(window.data()) : std::max(loudest, energy_db(window.data()));
    }
    // 2. Again: kept frames overlap-added; each finished hop of the result
    // goes on to the envelope frames; each envelope frame to the segments.
    x.rewind();
    y.rewind();
    std::vector<double> acc_x(kFrame, 0.0), acc_y(kFrame, 0.0);   // the overlap-add's open frame
    std::vector<double> env_x(kFrame), env_y(kFrame);             // the envelope analysis window
    std::size_t hops_out = 0;                                     // finished hops of the result
    EnvelopeAnalyser analyse;
    std::array<Envelope, kSegment> X{}, Y{};
    std::size_t envelope_frames = 0;
    double total = 0.0;
    std::size_t segments = 0;
    std::size_t kept = 0;
    const double clip = std::pow(10.0, -kBetaDb / 20.0);
    // A finished hop of the result (both signals): into the envelope window.
    // The result, (kept - 1)·hop + frame long, has kept − 1 envelope frames
    // (frame_count): the frame completed by the last hop is not one of them.
    auto hop_done = [&](const double* hx, const double* hy, bool last) {
        std::copy(env_x.begin() + kHop, env_x.end(), env_x.begin());
        std::copy(env_y.begin() + kHop, env_y.end(), env_y.begin());
        std::copy_n(hx, kHop, env_x.begin() + kHop);
        std::copy_n(hy, kHop, env_y.begin() + kHop);
        ++hops_out;
        if (hops_out < 2) return;
        const std::size_t g = hops_out - 2;  // the envelope frame now complete
        if (last) return;
        X[g % kSegment] = analyse(env_x.data());
        Y[g % kSegment] = analyse(env_y.data());
        envelope_frames = g + 1;
        if (envelope_frames < kSegment) return;
        // 3. The segment ending at frame g.
        const std::size_t m = g + 1 - kSegment;
        ++segments;
        if (extended) {
            total += estoi_segment(X, Y, m);
            return;
        }
        std::array<std::array<double, kSegment>, kBands> xs{}, ys{};
        for (std::size_t j = 0; j < kBands; ++j)
            for (std::size_t n = 0; n < kSegment; ++n) {
                xs[j][n] = X[(m + n) % kSegment][j];
                ys[j][n] = Y[(m + n) % kSegment][j];
            }
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
    };
    for (std::size_t f = 0; f < frames; ++f) {
        slide(x, window, f);
        slide(y, window_y, f);
        if (!(loudest - kDynamicRangeDb - energy_db(window.data()) < 0.0)) continue;
        // Overlap-add the kept frame at hop `kept`, then pass on the hop
        // that no later frame reaches.
        for (std::size_t i = 0; i < kFrame; ++i) {
            acc_x[i] += w[i] * window[i];
            acc_y[i] += w[i] * window_y[i];
        }
        ++kept;
        hop_done(acc_x.data(), acc_y.data(), false);
        std::copy(acc_x.begin() + kHop, acc_x.end(), acc_x.begin());
        std::copy(acc_y.begin() + kHop, acc_y.end(), acc_y.begin());
        std::fill(acc_x.begin() + kHop, acc_x.end(), 0.0);
        std::fill(acc_y.begin() + kHop, acc_y.end(), 0.0);
    }
    if (kept > 0) hop_done(acc_x.data(), acc_y.data(), true);  // the last frame's second half
    if (envelope_frames < kSegment)
        throw InputError(Diagnostic{
            "", 0, 0, "stoi",
            fmt::format("expected at least {} non-silent frames (about 0.4 s of speech at 10 kHz), got {}", kSegment,
                        envelope_frames)});
    // 4. The mean over segments (and bands).
    return total / static_cast<double>(segments);
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
    SpanInput x(clean), y(degraded);
    return stoi_of(x, y, sample_rate_hz, settings.extended);
}

double stoi(AudioSource& clean, AudioSource& degraded, const StoiSettings& settings) {
    if (!(clean.sample_rate_hz() > 0))
        throw InputError(Diagnostic{"", 0, 0, "stoi",
                                    fmt::format("expected a positive sample rate, got {}", clean.sample_rate_hz())});
    if (clean.sample_rate_hz() != degraded.sample_rate_hz())
        throw InputError(Diagnostic{"", 0, 0, "stoi",
                                    fmt::format("expected clean and degraded audio at the same sample rate, got "
                                                "{} Hz and {} Hz",
                                                clean.sample_rate_hz(), degraded.sample_rate_hz())});
    if (clean.frames() != degraded.frames())
        throw InputError(Diagnostic{"", 0, 0, "stoi",
                                    fmt::format("expected clean and degraded signals of the same length, got {} "
                                                "and {} samples",
                                                clean.frames(), degraded.frames())});
    SourceInput x(clean), y(degraded);
    return stoi_of(x, y, clean.sample_rate_hz(), settings.extended);
}

double stoi(const Audio& clean, const Audio& degraded, const StoiSettings& settings) {
    AudioBufferSource x(clean), y(degraded);
    return stoi(x, y, settings);
}

std::vector<double> stoi_files(const std::filesystem::path& clean_path, const std::filesystem::path& degraded_path,
                               const StoiSettings& settings, ChannelMode channels) {
    const std::string c = clean_path.string(), d = degraded_path.string();
    AudioFileReader clean_reader(clean_path), degraded_reader(degraded_path);
    const int rate = clean_reader.sample_rate_hz();
    if (rate != degraded_reader.sample_rate_hz())
        throw InputError(d, 0, 0, "sample rate",
                         fmt::format("expected the sample rate of {} ({} Hz), got {} Hz", c, rate,
                                     degraded_reader.sample_rate_hz()));
    const std::size_t clean_frames = clean_reader.frames(), degraded_frames = degraded_reader.frames();
    if (clean_frames != degraded_frames)
        throw InputError(d, 0, 0, "length",
                         fmt::format("expected as many samples as {} ({}, {:.3f} s), got {} ({:.3f} s): STOI compares "
                                     "the signals frame by frame, so they must be aligned and of one length",
                                     c, clean_frames, static_cast<double>(clean_frames) / rate, degraded_frames,
                                     static_cast<double>(degraded_frames) / rate));
    if (channels == ChannelMode::Keep && clean_reader.channels() != degraded_reader.channels())
        throw InputError(d, 0, 0, "channels",
                         fmt::format("expected the channel count of {} ({}) with --channels keep, got {}", c,
                                     clean_reader.channels(), degraded_reader.channels()));
    // Diagnostics without a path name the degraded file.
    auto naming = [&](auto&& score) {
        try {
            return score();
        } catch (const InputError& e) {
            std::vector<Diagnostic> diagnostics = e.diagnostics();
            for (Diagnostic& diag : diagnostics)
                if (diag.path.empty()) diag.path = d;
            throw InputError(std::move(diagnostics));
        }
    };
    // Two mono files: read block by block (memory bounded whatever the length).
    if (clean_reader.channels() == 1 && degraded_reader.channels() == 1)
        return {naming([&] { return stoi(clean_reader, degraded_reader, settings); })};
    const Audio clean = read_audio(clean_path), degraded = read_audio(degraded_path);
    auto score = [&](const std::vector<float>& a, const std::vector<float>& b) {
        const std::vector<double> x(a.begin(), a.end()), y(b.begin(), b.end());
        return naming([&] { return stoi(x, y, clean.sample_rate_hz, settings); });
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
