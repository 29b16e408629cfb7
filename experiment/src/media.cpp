// Test pattern, null audio device and frame pacing (see media.h).
#include "avsi/experiment/media.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "avsi/core/error.h"

namespace avsi::experiment {

namespace {

class TestPattern : public FrameSource {
public:
    explicit TestPattern(const TestPatternSettings& s) : m_s(s) {
        m_count = std::max(1, static_cast<int>(std::lround(s.duration_s * s.fps)));
        const auto samples = static_cast<std::size_t>(std::lround(m_count / s.fps * s.sample_rate));
        m_audio.assign(samples, 0.0f);
        const auto burst = static_cast<std::size_t>(0.010 * s.sample_rate);
        for (int k = 0; k < m_count; ++k) {
            const auto start = static_cast<std::size_t>(std::lround(k / s.fps * s.sample_rate));
            for (std::size_t i = 0; i < burst && start + i < samples; ++i)
                m_audio[start + i] = static_cast<float>(
                    0.3 * std::sin(2.0 * std::numbers::pi * s.click_hz * static_cast<double>(i) / s.sample_rate));
        }
    }
    int width() const override { return m_s.width; }
    int height() const override { return m_s.height; }
    double fps() const override { return m_s.fps; }
    int frame_count() const override { return m_count; }
    const std::vector<float>& audio() const override { return m_audio; }
    int sample_rate() const override { return m_s.sample_rate; }

    bool next_frame(VideoFrame& f) override {
        if (m_next >= m_count) return false;
        const int k = m_next++;
        f.width = m_s.width;
        f.height = m_s.height;
        f.index = k;
        f.pts_s = k / m_s.fps;
        f.rgba.resize(static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height) * 4);
        // Background hue cycles with the frame; a bar sweeps left to right;
        // the frame index is drawn as 8 binary blocks along the top.
        const double phase = static_cast<double>(k) / m_count;
        const auto r = static_cast<std::uint8_t>(128 + 100 * std::sin(2 * std::numbers::pi * phase));
        const auto g = static_cast<std::uint8_t>(128 + 100 * std::sin(2 * std::numbers::pi * (phase + 1.0 / 3)));
        const auto b = static_cast<std::uint8_t>(128 + 100 * std::sin(2 * std::numbers::pi * (phase + 2.0 / 3)));
        const int bar_x = static_cast<int>(phase * f.width);
        const int block = std::max(1, f.width / 8);
        for (int y = 0; y < f.height; ++y) {
            for (int x = 0; x < f.width; ++x) {
                std::uint8_t* px = &f.rgba[(static_cast<std::size_t>(y) * f.width + x) * 4];
                std::uint8_t c[3] = {r, g, b};
                if (std::abs(x - bar_x) < std::max(2, f.width / 64)) c[0] = c[1] = c[2] = 255;
                if (y < f.height / 10) {
                    const int bit = 7 - std::min(7, x / block);
                    const std::uint8_t v = ((k >> bit) & 1) ? 255 : 0;
                    c[0] = c[1] = c[2] = v;
                }
                px[0] = c[0];
                px[1] = c[1];
                px[2] = c[2];
                px[3] = 255;
            }
        }
        return true;
    }

private:
    TestPatternSettings m_s;
    int m_count = 0;
    int m_next = 0;
    std::vector<float> m_audio;
};

}  // namespace

std::unique_ptr<FrameSource> make_test_pattern(const TestPatternSettings& settings) {
    AVSI_ASSERT(settings.fps > 0 && settings.duration_s > 0 && settings.width > 0 && settings.height > 0);
    return std::make_unique<TestPattern>(settings);
}

std::unique_ptr<FrameSource> TestPatternOpener::open(const std::string&) { return make_test_pattern(m_settings); }

void NullAudioOutput::play(const std::vector<float>& samples, int sample_rate, double at_s) {
    m_onset_s = std::max(at_s, m_now_s);
    m_duration_s = sample_rate > 0 ? static_cast<double>(samples.size()) / sample_rate : 0.0;
}

bool NullAudioOutput::playing() { return m_onset_s && m_now_s < *m_onset_s + m_duration_s; }

void NullAudioOutput::stop() {
    m_onset_s.reset();
    m_duration_s = 0.0;
}

FramePacer::FramePacer(double fps, int frame_count, double refresh_hz)
    : m_fps(fps), m_frame_count(frame_count), m_refresh_hz(refresh_hz),
      m_flips_per_frame(static_cast<std::size_t>(std::max(0, frame_count)), 0) {
    AVSI_ASSERT(fps > 0 && refresh_hz > 0);
}

void FramePacer::start(double audio_onset_s) {
    m_onset_s = audio_onset_s;
    std::fill(m_flips_per_frame.begin(), m_flips_per_frame.end(), 0);
    m_first_flips.clear();
}

int FramePacer::frame_for(double flip_s) const {
    const double t = flip_s - m_onset_s;
    // Half a microsecond of slack absorbs rounding in the clock sums.
    if (t < -0.5e-6) return -1;
    const int k = static_cast<int>(std::floor(t * m_fps + 0.5e-6 * m_fps));
    return std::min(k, m_frame_count);
}

void FramePacer::flipped(int frame, double pts_s, double flip_s) {
    AVSI_ASSERT(frame >= 0 && frame < m_frame_count);
    if (m_flips_per_frame[static_cast<std::size_t>(frame)]++ == 0)
        m_first_flips.push_back({frame, pts_s, flip_s, ((flip_s - m_onset_s) - pts_s) * 1000.0});
}

Presentation FramePacer::summary() const {
    Presentation p;
    p.audio_onset_s = m_onset_s;
    p.video_onset_s = m_first_flips.empty() ? 0.0 : m_first_flips.front().flip_s;
    p.duration_s = m_frame_count / m_fps;
    p.refresh_hz = m_refresh_hz;
    p.frames_total = m_frame_count;
    const int allowed = static_cast<int>(std::ceil(m_refresh_hz / m_fps - 1e-9));
    double sum = 0.0;
    for (std::size_t k = 0; k < m_flips_per_frame.size(); ++k) {
        const int n = m_flips_per_frame[k];
        if (n == 0) ++p.dropped_frames;
        else ++p.frames_shown;
        if (n > allowed) ++p.repeated_frames;
    }
    for (const auto& f : m_first_flips) {
        sum += f.offset_ms;
        p.max_abs_offset_ms = std::max(p.max_abs_offset_ms, std::fabs(f.offset_ms));
    }
    p.mean_offset_ms = m_first_flips.empty() ? 0.0 : sum / static_cast<double>(m_first_flips.size());
    p.flips = m_first_flips;
    return p;
}

}  // namespace avsi::experiment
