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

namespace avsi::vocoder {

struct StreamResampler::Soxr {
    soxr_t handle = nullptr;
    ~Soxr() {
        if (handle) soxr_delete(handle);
    }
};

StreamResampler::StreamResampler(double from_hz, double to_hz, std::size_t input_frames)
    : m_input_frames(input_frames) {
    AVSI_ASSERT(from_hz > 0.0 && to_hz > 0.0);
    if (from_hz == to_hz || input_frames == 0) {
        m_output_frames = input_frames;
        return;
    }
    m_output_frames = static_cast<std::size_t>(std::llround(static_cast<double>(input_frames) * to_hz / from_hz));
    // As soxr_oneshot sets it up (resample()).
    const soxr_io_spec_t io = soxr_io_spec(SOXR_FLOAT64_I, SOXR_FLOAT64_I);
    const soxr_quality_spec_t quality = soxr_quality_spec(SOXR_VHQ, SOXR_LINEAR_PHASE);
    soxr_error_t error = nullptr;
    m_soxr = std::make_unique<Soxr>();
    m_soxr->handle = soxr_create(from_hz, to_hz, 1, &error, &io, &quality, nullptr);
    if (error) throw std::runtime_error(std::string("libsoxr: resampling failed: ") + error);
}

StreamResampler::~StreamResampler() = default;

void StreamResampler::feed(const double* in, std::size_t count, std::vector<double>& out) {
    AVSI_ASSERT(m_fed + count <= m_input_frames);
    m_fed += count;
    const bool last = m_fed == m_input_frames;
    if (!m_soxr) {
        out.insert(out.end(), in, in + count);
        return;
    }
    // Output in pieces of at most kRoom samples until this input is taken
    // (soxr keeps what it cannot finish yet) and, after the last input,
    // until soxr has nothing more.
    constexpr std::size_t kRoom = 16384;
    std::size_t offered = 0;
    for (;;) {
        const std::size_t room = std::min(kRoom, m_output_frames - m_produced);
        const std::size_t before = out.size();
        out.resize(before + room);
        std::size_t used = 0, done = 0;
        // soxr_oneshot passes the input length complemented (~n) to mean "the last input".
        const std::size_t length = count - offered;
        const soxr_error_t error = soxr_process(m_soxr->handle, in + offered, last ? ~length : length, &used,
                                                out.data() + before, room, &done);
        if (error) throw std::runtime_error(std::string("libsoxr: resampling failed: ") + error);
        out.resize(before + done);
        m_produced += done;
        offered += used;
        // All output there is to give (as soxr_oneshot stops at its length).
        if (m_produced == m_output_frames) break;
        const bool input_taken = offered >= count;
        if (input_taken && (!last || done == 0)) break;
        if (!input_taken && used == 0 && done == 0)
            throw std::runtime_error("libsoxr: the resampler took no input and gave no output");
    }
    if (last && m_produced < m_output_frames) {
        out.resize(out.size() + (m_output_frames - m_produced), 0.0);
        m_produced = m_output_frames;
    }
}

}  // namespace avsi::vocoder
