// Speech-shaped noise and mixing at an SNR; see masking.h.
#include "avsi/vocoder/masking.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include <fmt/format.h>
#include <unsupported/Eigen/FFT>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/vocoder/channels.h"
#include "avsi/core/rng.h"
#include "avsi/vocoder/hilbert.h"
#include "avsi/vocoder/resample.h"

namespace avsi::vocoder {

double LongTermSpectrum::at(double f) const {
    if (power.empty() || f < 0.0) return 0.0;
    const double bin = f * static_cast<double>(fft_size) / sample_rate_hz;
    const auto k = static_cast<std::size_t>(bin);
    if (k + 1 >= power.size()) return k + 1 == power.size() && bin == static_cast<double>(k) ? power[k] : 0.0;
    const double t = bin - static_cast<double>(k);
    return (1.0 - t) * power[k] + t * power[k + 1];
}

LongTermSpectrum long_term_spectrum(const std::vector<Audio>& recordings, std::size_t fft_size) {
    if (recordings.empty())
        throw InputError(Diagnostic{"", 0, 0, "noise", "expected at least one recording for the long-term spectrum, got none"});
    AVSI_ASSERT(fft_size >= 16 && fft_size % 2 == 0);
    LongTermSpectrum ltas;
    ltas.sample_rate_hz = recordings.front().sample_rate_hz;
    ltas.fft_size = fft_size;
    ltas.power.assign(fft_size / 2 + 1, 0.0);
    std::vector<double> window(fft_size);
    for (std::size_t i = 0; i < fft_size; ++i)
        window[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(fft_size));
    Eigen::FFT<double> fft;
    std::vector<double> frame(fft_size);
    std::vector<std::complex<double>> spectrum;
    std::size_t frames = 0;
    for (const Audio& audio : recordings) {
        const std::vector<float> mono = audio.mono();
        std::vector<double> x(mono.begin(), mono.end());
        if (audio.sample_rate_hz != ltas.sample_rate_hz) x = resample(x, audio.sample_rate_hz, ltas.sample_rate_hz);
        for (std::size_t start = 0; start + fft_size <= x.size(); start += fft_size / 2) {
            for (std::size_t i = 0; i < fft_size; ++i) frame[i] = window[i] * x[start + i];
            fft.fwd(spectrum, frame);
            for (std::size_t k = 0; k < ltas.power.size(); ++k) ltas.power[k] += std::norm(spectrum[k]);
            ++frames;
        }
    }
    if (frames == 0)
        throw InputError(Diagnostic{"", 0, 0, "noise",
                                    fmt::format("expected recordings of at least {} samples for the long-term "
                                                "spectrum, got shorter ones",
                                                fft_size)});
    for (double& p : ltas.power) p /= static_cast<double>(frames);
    return ltas;
}

std::vector<double> speech_shaped_noise(const LongTermSpectrum& spectrum, std::size_t frames, double rate,
                                        std::uint64_t seed) {
    if (frames == 0) return {};
    const std::size_t m = fast_fft_size(frames);
    Rng rng = Rng(seed).derive("speech-shaped-noise");
    std::vector<double> white(m);
    for (double& v : white) v = rng.normal();
    Eigen::FFT<double> fft;
    std::vector<std::complex<double>> X;
    fft.fwd(X, white);
    for (std::size_t k = 0; k < m; ++k) {
        const std::size_t folded = std::min(k, m - k);  // the negative frequencies mirror the positive
        X[k] *= std::sqrt(spectrum.at(rate * static_cast<double>(folded) / static_cast<double>(m)));
    }
    std::vector<std::complex<double>> shaped;
    fft.inv(shaped, X);
    std::vector<double> out(frames);
    double sum_sq = 0.0;
    for (std::size_t i = 0; i < frames; ++i) {
        out[i] = shaped[i].real();
        sum_sq += out[i] * out[i];
    }
    const double rms = std::sqrt(sum_sq / static_cast<double>(frames));
    if (rms > 0.0)
        for (double& v : out) v /= rms;
    return out;
}

std::string to_string(SnrReference reference) {
    return reference == SnrReference::WholeSignal ? "whole" : "active";
}

SnrReference parse_snr_reference(const std::string& text, const std::string& field) {
    if (text == "whole") return SnrReference::WholeSignal;
    if (text == "active") return SnrReference::ActiveFrames;
    throw InputError(Diagnostic{"", 0, 0, field, fmt::format("expected one of whole, active, got \"{}\"", text)});
}

double speech_level_rms(std::span<const double> x, double rate, SnrReference reference) {
    if (x.empty()) return 0.0;
    if (reference == SnrReference::WholeSignal) {
        double s = 0.0;
        for (double v : x) s += v * v;
        return std::sqrt(s / static_cast<double>(x.size()));
    }
    // 20 ms frames; those within 40 dB of the loudest count as active.
    const auto frame = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(0.02 * rate)));
    std::vector<double> energy;
    for (std::size_t start = 0; start < x.size(); start += frame) {
        double s = 0.0;
        for (std::size_t i = start; i < std::min(x.size(), start + frame); ++i) s += x[i] * x[i];
        energy.push_back(s);
    }
    std::vector<double> mean_sq(energy.size());
    for (std::size_t f = 0; f < energy.size(); ++f)
        mean_sq[f] = energy[f] / static_cast<double>(std::min(frame, x.size() - f * frame));
    const double loudest = *std::max_element(mean_sq.begin(), mean_sq.end());
    if (loudest <= 0.0) return 0.0;
    double sum = 0.0;
    std::size_t count = 0;
    for (std::size_t f = 0; f < energy.size(); ++f)
        if (mean_sq[f] >= loudest * 1e-4) {  // -40 dB
            sum += energy[f];
            count += std::min(frame, x.size() - f * frame);
        }
    return std::sqrt(sum / static_cast<double>(count));
}

namespace {

constexpr std::size_t kBlock = 8192;

// Reads frames [first, first + count) of `source` (positioned at `first`)
// into `block`, or throws when it ends early.
void read_fully(AudioSource& source, float* block, std::size_t count) {
    std::size_t got = 0;
    const std::size_t channels = static_cast<std::size_t>(source.channels());
    while (got < count) {
        const std::size_t n = source.read(block + got * channels, count - got);
        if (n == 0)
            throw InputError(Diagnostic{"", 0, 0, "audio",
                                        fmt::format("expected {} frames, the input ended early", source.frames())});
        got += n;
    }
}

// Calls f(mono, count) for each block of the source from its start, its
// channels mixed as Audio::mono mixes them.
template <typename F>
void for_each_mono_block(AudioSource& source, F&& f) {
    const std::size_t channels = static_cast<std::size_t>(source.channels());
    const std::size_t frames = source.frames();
    std::vector<float> block(kBlock * channels);
    std::vector<double> mono(kBlock);
    source.seek(0);
    for (std::size_t first = 0; first < frames; first += kBlock) {
        const std::size_t count = std::min(kBlock, frames - first);
        read_fully(source, block.data(), count);
        for (std::size_t i = 0; i < count; ++i) {
            if (channels == 1) {
                mono[i] = block[i];
                continue;
            }
            float sum = 0.0f;
            for (std::size_t c = 0; c < channels; ++c) sum += block[i * channels + c];
            mono[i] = sum / static_cast<float>(channels);
        }
        f(mono.data(), count);
    }
}

// The excerpt of the noise the speech gets: from `offset` in a noise at
// least as long, or the noise looped.
struct Excerpt {
    std::size_t offset = 0;
    bool loop = false;

    void read(NoiseSamples& noise, std::size_t first, std::size_t count, double* out) const {
        if (!loop) return noise.read(offset + first, count, out);
        const std::size_t length = noise.frames();
        while (count > 0) {
            const std::size_t at = first % length;
            const std::size_t n = std::min(count, length - at);
            noise.read(at, n, out);
            first += n;
            count -= n;
            out += n;
        }
    }
};

}  // namespace

double speech_level_rms(AudioSource& speech, SnrReference reference) {
    const std::size_t frames = speech.frames();
    if (frames == 0) return 0.0;
    if (reference == SnrReference::WholeSignal) {
        double s = 0.0;
        for_each_mono_block(speech, [&](const double* x, std::size_t n) {
            for (std::size_t i = 0; i < n; ++i) s += x[i] * x[i];
        });
        return std::sqrt(s / static_cast<double>(frames));
    }
    // 20 ms frames; those within 40 dB of the loudest count as active. Two
    // passes: the loudest frame, then the active frames' energy.
    const auto frame = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(0.02 * speech.sample_rate_hz())));
    // Calls g(energy, length) per 20 ms frame, in order.
    auto for_each_frame = [&](auto&& g) {
        double energy = 0.0;
        std::size_t filled = 0;
        for_each_mono_block(speech, [&](const double* x, std::size_t n) {
            for (std::size_t i = 0; i < n; ++i) {
                energy += x[i] * x[i];
                if (++filled == frame) {
                    g(energy, filled);
                    energy = 0.0;
                    filled = 0;
                }
            }
        });
        if (filled > 0) g(energy, filled);
    };
    double loudest = -INFINITY;
    for_each_frame([&](double energy, std::size_t length) {
        loudest = std::max(loudest, energy / static_cast<double>(length));
    });
    if (loudest <= 0.0) return 0.0;
    double sum = 0.0;
    std::size_t count = 0;
    for_each_frame([&](double energy, std::size_t length) {
        if (energy / static_cast<double>(length) >= loudest * 1e-4) {  // -40 dB
            sum += energy;
            count += length;
        }
    });
    return std::sqrt(sum / static_cast<double>(count));
}

void NoiseInMemory::read(std::size_t from, std::size_t count, double* out) {
    AVSI_ASSERT(from + count <= m_noise.size());
    std::copy_n(m_noise.begin() + static_cast<std::ptrdiff_t>(from), count, out);
}

NoiseFile::NoiseFile(const std::filesystem::path& path) : m_reader(path) {
    if (m_reader.frames() == 0) throw InputError(path, "expected a noise recording with samples, got an empty file");
    // As load_noise: a silent recording has no level to set (read up to its
    // first non-zero sample).
    const std::size_t channels = static_cast<std::size_t>(m_reader.channels());
    m_block.resize(kBlock * channels);
    bool energy = false;
    for (std::size_t done = 0; done < m_reader.frames() && !energy;) {
        const std::size_t n = std::min(kBlock, m_reader.frames() - done);
        read_fully(m_reader, m_block.data(), n);
        for (std::size_t i = 0; i < n * channels && !energy; ++i) energy = m_block[i] != 0.0f;
        done += n;
    }
    if (!energy) throw InputError(path, "expected a noise recording with energy, got silence");
    m_reader.seek(0);
    m_position = 0;
}

void NoiseFile::read(std::size_t from, std::size_t count, double* out) {
    AVSI_ASSERT(from + count <= m_reader.frames());
    if (from != m_position) m_reader.seek(from);
    const std::size_t channels = static_cast<std::size_t>(m_reader.channels());
    m_block.resize(std::min(count, kBlock) * channels);
    for (std::size_t done = 0; done < count;) {
        const std::size_t n = std::min(kBlock, count - done);
        read_fully(m_reader, m_block.data(), n);
        for (std::size_t i = 0; i < n; ++i) {
            if (channels == 1) {
                out[done + i] = m_block[i];
                continue;
            }
            float sum = 0.0f;
            for (std::size_t c = 0; c < channels; ++c) sum += m_block[i * channels + c];
            out[done + i] = sum / static_cast<float>(channels);
        }
        done += n;
    }
    m_position = from + count;
}

MixedSource::MixedSource(AudioSource& speech, NoiseSamples& noise, const MixSettings& settings)
    : m_speech(speech), m_noise(noise) {
    if (noise.frames() == 0)
        throw InputError(Diagnostic{"", 0, 0, "noise", "expected a noise signal with samples, got an empty one"});
    if (!std::isfinite(settings.snr_db))
        throw InputError(Diagnostic{"", 0, 0, "snr_db", fmt::format("expected a finite SNR in dB, got {}", settings.snr_db)});
    const std::size_t frames = speech.frames();
    if (frames == 0) return;
    // The noise excerpt: a seeded offset into a longer noise, a loop of a shorter one.
    Excerpt excerpt;
    if (noise.frames() >= frames) {
        Rng rng = Rng(settings.seed).derive("noise-offset");
        excerpt.offset = rng.uniform_int(noise.frames() - frames + 1);
    } else {
        log_info("noise ({} samples) is shorter than the speech ({} samples); looping it", noise.frames(), frames);
        excerpt.loop = true;
    }
    m_offset = excerpt.offset;
    m_report.speech_rms = speech_level_rms(speech, settings.reference);
    double noise_sq = 0.0;
    m_noise_block.resize(kBlock);
    for (std::size_t first = 0; first < frames; first += kBlock) {
        const std::size_t count = std::min(kBlock, frames - first);
        excerpt.read(noise, first, count, m_noise_block.data());
        for (std::size_t i = 0; i < count; ++i) noise_sq += m_noise_block[i] * m_noise_block[i];
    }
    const double noise_rms = std::sqrt(noise_sq / static_cast<double>(frames));
    if (noise_rms == 0.0)
        throw InputError(Diagnostic{"", 0, 0, "noise", "expected a noise signal with energy, got silence"});
    m_gain = m_report.speech_rms * std::pow(10.0, -settings.snr_db / 20.0) / noise_rms;
    m_report.noise_rms = noise_rms * m_gain;
    // The mixture's peak.
    const std::size_t channels = static_cast<std::size_t>(speech.channels());
    m_speech_block.resize(kBlock * channels);
    double peak = 0.0;
    speech.seek(0);
    for (std::size_t first = 0; first < frames; first += kBlock) {
        const std::size_t count = std::min(kBlock, frames - first);
        read_fully(speech, m_speech_block.data(), count);
        excerpt.read(noise, first, count, m_noise_block.data());
        for (std::size_t i = 0; i < count; ++i)
            for (std::size_t c = 0; c < channels; ++c)
                peak = std::max(peak, std::abs(m_speech_block[i * channels + c] + m_gain * m_noise_block[i]));
    }
    if (peak > 1.0) {
        m_scale = 0.999 / peak;
        m_report.limit_gain_db = 20.0 * std::log10(m_scale);
        log_warning("mix: speech plus noise peaks at {:.3f}; scaled the mixture by {:.2f} dB to avoid clipping "
                    "(the SNR is unchanged)",
                    peak, m_report.limit_gain_db);
    }
    m_loop = excerpt.loop;
    seek(0);
}

std::size_t MixedSource::read(float* out, std::size_t frames) {
    const std::size_t n = std::min(frames, m_speech.frames() - m_position);
    if (n == 0) return 0;
    const std::size_t channels = static_cast<std::size_t>(m_speech.channels());
    read_fully(m_speech, out, n);
    if (m_noise_block.size() < n) m_noise_block.resize(n);
    Excerpt{m_offset, m_loop}.read(m_noise, m_position, n, m_noise_block.data());
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t c = 0; c < channels; ++c) {
            const double mixed = out[i * channels + c] + m_gain * m_noise_block[i];
            out[i * channels + c] = static_cast<float>(mixed * m_scale);
        }
    m_position += n;
    return n;
}

void MixedSource::seek(std::size_t frame) {
    m_speech.seek(frame);
    m_position = frame;
}

MixReport mix_stream(AudioSource& speech, NoiseSamples& noise, const MixSettings& settings, AudioSink& output) {
    MixedSource mixed(speech, noise, settings);
    const std::size_t channels = static_cast<std::size_t>(speech.channels());
    std::vector<float> block(kBlock * channels);
    while (const std::size_t n = mixed.read(block.data(), kBlock)) output.write(block.data(), n);
    return mixed.report();
}

MixResult mix_at_snr(const Audio& speech, std::span<const double> noise, const MixSettings& settings) {
    MixResult result;
    AudioBufferSource source(speech);
    NoiseInMemory samples(noise);
    result.audio.sample_rate_hz = speech.sample_rate_hz;
    result.audio.channels = speech.channels;
    result.audio.samples.reserve(speech.samples.size());
    AudioBufferSink sink(result.audio);
    const MixReport report = mix_stream(source, samples, settings, sink);
    result.speech_rms = report.speech_rms;
    result.noise_rms = report.noise_rms;
    result.limit_gain_db = report.limit_gain_db;
    return result;
}

std::vector<double> load_noise(const std::filesystem::path& path, double rate) {
    const Audio noise = mix_down(read_audio(path), path.string(), "as masking noise (one noise is added to every channel)");
    const std::vector<float> mono = noise.mono();
    std::vector<double> x(mono.begin(), mono.end());
    if (noise.sample_rate_hz != rate) {
        log_info("{}: resampling the noise from {} Hz to {} Hz", path.string(), noise.sample_rate_hz, rate);
        x = resample(x, noise.sample_rate_hz, rate);
    }
    if (x.empty()) throw InputError(path, "expected a noise recording with samples, got an empty file");
    double energy = 0.0;
    for (double v : x) energy += v * v;
    if (energy == 0.0) throw InputError(path, "expected a noise recording with energy, got silence");
    return x;
}

}  // namespace avsi::vocoder
