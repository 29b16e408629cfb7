// Sample-rate conversion with libsoxr's one-shot interface.
#include "avsi/vocoder/resample.h"

#include <soxr.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "avsi/core/error.h"

namespace avsi::vocoder {

std::vector<double> resample(std::span<const double> signal, double from_hz, double to_hz) {
    AVSI_ASSERT(from_hz > 0.0 && to_hz > 0.0);
    if (from_hz == to_hz || signal.empty()) return {signal.begin(), signal.end()};
    const auto out_length =
        static_cast<std::size_t>(std::llround(static_cast<double>(signal.size()) * to_hz / from_hz));
    std::vector<double> out(out_length);
    const soxr_io_spec_t io = soxr_io_spec(SOXR_FLOAT64_I, SOXR_FLOAT64_I);
    const soxr_quality_spec_t quality = soxr_quality_spec(SOXR_VHQ, SOXR_LINEAR_PHASE);
    std::size_t done = 0;
    const soxr_error_t error = soxr_oneshot(from_hz, to_hz, 1, signal.data(), signal.size(), nullptr,
                                            out.data(), out.size(), &done, &io, &quality, nullptr);
    if (error) throw std::runtime_error(std::string("libsoxr: resampling failed: ") + error);
    out.resize(done);
    out.resize(out_length, 0.0);
    return out;
}

}  // namespace avsi::vocoder
