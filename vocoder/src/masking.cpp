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

MixResult mix_at_snr(const Audio& speech, std::span<const double> noise, const MixSettings& settings) {
    if (noise.empty())
        throw InputError(Diagnostic{"", 0, 0, "noise", "expected a noise signal with samples, got an empty one"});
    if (!std::isfinite(settings.snr_db))
        throw InputError(Diagnostic{"", 0, 0, "snr_db", fmt::format("expected a finite SNR in dB, got {}", settings.snr_db)});
    const std::size_t frames = speech.frames();
    MixResult result;
    result.audio = speech;
    if (frames == 0) return result;
    // The noise excerpt: a seeded offset into a longer noise, a loop of a shorter one.
    std::vector<double> n(frames);
    if (noise.size() >= frames) {
        Rng rng = Rng(settings.seed).derive("noise-offset");
        const std::size_t offset = rng.uniform_int(noise.size() - frames + 1);
        std::copy_n(noise.begin() + static_cast<std::ptrdiff_t>(offset), frames, n.begin());
    } else {
        log_info("noise ({} samples) is shorter than the speech ({} samples); looping it", noise.size(), frames);
        for (std::size_t i = 0; i < frames; ++i) n[i] = noise[i % noise.size()];
    }
    const std::vector<float> mono = speech.mono();
    const std::vector<double> s(mono.begin(), mono.end());
    result.speech_rms = speech_level_rms(s, speech.sample_rate_hz, settings.reference);
    double noise_sq = 0.0;
    for (double v : n) noise_sq += v * v;
    const double noise_rms = std::sqrt(noise_sq / static_cast<double>(frames));
    if (noise_rms == 0.0)
        throw InputError(Diagnostic{"", 0, 0, "noise", "expected a noise signal with energy, got silence"});
    const double gain = result.speech_rms * std::pow(10.0, -settings.snr_db / 20.0) / noise_rms;
    result.noise_rms = noise_rms * gain;
    std::vector<double> mixed(speech.samples.size());
    double peak = 0.0;
    for (std::size_t i = 0; i < frames; ++i)
        for (int c = 0; c < speech.channels; ++c) {
            const std::size_t k = i * speech.channels + c;
            mixed[k] = speech.samples[k] + gain * n[i];
            peak = std::max(peak, std::abs(mixed[k]));
        }
    double scale = 1.0;
    if (peak > 1.0) {
        scale = 0.999 / peak;
        result.limit_gain_db = 20.0 * std::log10(scale);
        log_warning("mix: speech plus noise peaks at {:.3f}; scaled the mixture by {:.2f} dB to avoid clipping "
                    "(the SNR is unchanged)",
                    peak, result.limit_gain_db);
    }
    for (std::size_t k = 0; k < mixed.size(); ++k) result.audio.samples[k] = static_cast<float>(mixed[k] * scale);
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
