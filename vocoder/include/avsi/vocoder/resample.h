// Sample-rate conversion through libsoxr (the SoX resampler, "very high
// quality" recipe: linear phase, passband to 95 % of the lower Nyquist,
// 175 dB stop-band rejection).
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

namespace avsi::vocoder {

// `signal` at `from_hz`, converted to `to_hz`. Output length is
// round(n · to/from), aligned in time with the input (the filter's group
// delay is removed). Returns a copy when the rates are equal.
std::vector<double> resample(std::span<const double> signal, double from_hz, double to_hz);

// resample() block by block: a signal of `input_frames` samples fed in
// pieces gives the same samples as resample() of the whole, in pieces.
class StreamResampler {
public:
    StreamResampler(double from_hz, double to_hz, std::size_t input_frames);
    ~StreamResampler();
    StreamResampler(const StreamResampler&) = delete;
    StreamResampler& operator=(const StreamResampler&) = delete;

    // The output length, round(n · to/from) (n when the rates are equal).
    std::size_t output_frames() const { return m_output_frames; }
    // Feeds the next `count` input samples and appends what is ready to
    // `out`; after the last input, appends the rest of the output.
    void feed(const double* in, std::size_t count, std::vector<double>& out);

private:
    struct Soxr;
    std::unique_ptr<Soxr> m_soxr;  // null when the rates are equal
    std::size_t m_input_frames = 0;
    std::size_t m_fed = 0;
    std::size_t m_output_frames = 0;
    std::size_t m_produced = 0;
};

}  // namespace avsi::vocoder
