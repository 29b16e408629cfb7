// MP4 output: decodes with the same libraries to the trajectory's frame
// count at its exact frame rate, audio as long as the video within one
// frame, both starting at 0, and byte-identical when written twice.
#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "avsi/core/files.h"
#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/video.h"

namespace avsi::stimuli {
namespace {

synth::Trajectory test_trajectory(std::size_t frames, double fps) {
    synth::Trajectory t;
    t.fps = fps;
    for (std::size_t k = 0; k < frames; ++k) {
        synth::Frame f{};
        f[synth::index(synth::Param::JawRotation)] = 0.5 + 0.5 * std::sin(double(k) * 0.3);
        f[synth::index(synth::Param::LipRounding)] = 0.5 * std::cos(double(k) * 0.2);
        t.frames.push_back(f);
    }
    return t;
}

Audio tone(double duration_s, int rate) {
    Audio a;
    a.sample_rate_hz = rate;
    a.samples.resize(static_cast<std::size_t>(duration_s * rate));
    for (std::size_t i = 0; i < a.samples.size(); ++i)
        a.samples[i] = 0.3f * static_cast<float>(std::sin(2.0 * M_PI * 220.0 * double(i) / rate));
    return a;
}

struct VideoFixture : ::testing::Test {
    std::filesystem::path dir = std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_avsi_video_test");
    void TearDown() override { std::filesystem::remove_all(dir); }
};

TEST_F(VideoFixture, DecodesToTheTrajectoryFrameCountRateAndAudioDuration) {
    static const Head head = load_default_head();
    RenderSettings rs;
    rs.width = 320;
    rs.height = 240;
    OffscreenRenderer renderer(head, rs);
    for (double fps : {30.0, 25.0, 60.0}) {
        SCOPED_TRACE(fps);
        const auto traj = test_trajectory(37, fps);
        const Audio audio = tone(traj.duration_s() - 0.4 / fps, 16000);  // audio a bit shorter than the video
        const auto path = dir / "out.mp4";
        render_video(renderer, traj, &audio, path);
        const DecodedVideo v = decode_video(path);
        EXPECT_EQ(v.frame_count, traj.size());
        EXPECT_DOUBLE_EQ(v.fps, fps);
        EXPECT_STREQ(v.video_codec, "h264");
        EXPECT_STREQ(v.pixel_format, "yuv420p");
        EXPECT_EQ(v.width, 320);
        ASSERT_TRUE(v.has_audio);
        EXPECT_DOUBLE_EQ(v.video_start_s, 0.0);
        EXPECT_NEAR(v.audio_start_s, 0.0, 1e-9);
        EXPECT_NEAR(v.audio.duration_s(), v.video_duration_s, 1.0 / fps);
    }
}

TEST_F(VideoFixture, SameInputGivesByteIdenticalFiles) {
    static const Head head = load_default_head();
    RenderSettings rs;
    rs.width = 320;
    rs.height = 240;
    OffscreenRenderer renderer(head, rs);
    const auto traj = test_trajectory(20, 30.0);
    const Audio audio = tone(traj.duration_s(), 22050);
    render_video(renderer, traj, &audio, dir / "a.mp4");
    render_video(renderer, traj, &audio, dir / "b.mp4");
    EXPECT_EQ(sha256_file(dir / "a.mp4"), sha256_file(dir / "b.mp4"));
}

TEST(Blinks, SeededAndWithinRange) {
    BlinkSettings s;
    s.seed = 7;
    const auto a = blink_track(600, 60.0, s), b = blink_track(600, 60.0, s);
    EXPECT_EQ(a, b);
    EXPECT_GT(*std::max_element(a.begin(), a.end()), 0.9);  // at least one blink in 10 s
    for (double v : a) EXPECT_TRUE(v >= 0.0 && v <= 1.0);
    s.seed = 8;
    EXPECT_NE(blink_track(600, 60.0, s), a);
}

}  // namespace
}  // namespace avsi::stimuli
