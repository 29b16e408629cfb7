// MP4 output: decodes with the same libraries to the trajectory's frame
// count at its exact frame rate, audio as long as the video within one
// frame, both starting at 0, and byte-identical when written twice.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>
#include <filesystem>

#include "avsi/core/files.h"
#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/video.h"
#include "support/heads.h"
#include "support/temp_dir.h"

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
    std::filesystem::path dir = test::temp_dir("video_test");
    void TearDown() override { std::filesystem::remove_all(dir); }
};

TEST_F(VideoFixture, DecodesToTheTrajectoryFrameCountRateAndAudioDuration) {
    const Head& head = test::default_head();
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
    const Head& head = test::default_head();
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

// Mean absolute difference per channel value between two same-size images.
double mean_abs_difference(const Image& a, const Image& b) {
    EXPECT_EQ(a.rgb.size(), b.rgb.size());
    double sum = 0.0;
    for (std::size_t i = 0; i < a.rgb.size() && i < b.rgb.size(); ++i) sum += std::abs(int(a.rgb[i]) - int(b.rgb[i]));
    return sum / double(std::max<std::size_t>(a.rgb.size(), 1));
}

// The encoder's RGB → YUV conversion (BT.601 limited range, written into the
// stream) decodes back to the rendered colours: only chroma subsampling and
// rounding differ. Swapped chroma planes or a full/limited range mix-up
// would give errors of tens of levels on the skin.
TEST_F(VideoFixture, DecodedFramesMatchTheRenderedColours) {
    const Head& head = test::default_head();
    RenderSettings rs;
    rs.width = 320;
    rs.height = 240;
    OffscreenRenderer renderer(head, rs);
    const auto traj = test_trajectory(6, 30.0);
    std::vector<Image> rendered;
    VideoSettings vs;
    vs.crf = 0;  // lossless H.264: what is decoded is exactly the converted YUV
    VideoWriter writer(dir / "lossless.mp4", 320, 240, traj.size(), nullptr, vs);
    for (std::size_t k = 0; k < traj.size(); ++k) {
        rendered.push_back(renderer.render(pose_at(traj, k, 0.0)));
        writer.write(rendered.back());
    }
    writer.finish();
    const DecodedVideo v = decode_video(dir / "lossless.mp4", true);
    ASSERT_EQ(v.frames.size(), rendered.size());
    for (std::size_t k = 0; k < rendered.size(); ++k) {
        SCOPED_TRACE(k);
        EXPECT_LT(mean_abs_difference(v.frames[k], rendered[k]), 1.5);
        // The centre pixel (the face) within a few levels per channel.
        const std::uint8_t* a = v.frames[k].pixel(160, 120);
        const std::uint8_t* b = rendered[k].pixel(160, 120);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 4) << "channel " << c;
    }
}

// Only the pixels that changed since the previous frame are converted; that
// must give exactly what converting the whole frame gives. With lossless
// encoding, each frame of a sequence decodes to the same picture as a
// one-frame video of it (converted whole).
TEST_F(VideoFixture, ConvertingOnlyChangedPixelsEqualsConvertingWholeFrames) {
    const Head& head = test::default_head();
    RenderSettings rs;
    rs.width = 320;
    rs.height = 240;
    OffscreenRenderer renderer(head, rs);
    const auto traj = test_trajectory(5, 30.0);
    VideoSettings vs;
    vs.crf = 0;
    std::vector<Image> rendered;
    {
        VideoWriter writer(dir / "sequence.mp4", 320, 240, traj.size(), nullptr, vs);
        for (std::size_t k = 0; k < traj.size(); ++k) {
            // Blink in frame 2 only: the eyes change, then change back.
            rendered.push_back(renderer.render(pose_at(traj, k, k == 2 ? 1.0 : 0.0)));
            writer.write(rendered.back());
        }
        writer.finish();
    }
    const DecodedVideo sequence = decode_video(dir / "sequence.mp4", true);
    ASSERT_EQ(sequence.frames.size(), rendered.size());
    for (std::size_t k = 0; k < rendered.size(); ++k) {
        SCOPED_TRACE(k);
        VideoWriter single(dir / "single.mp4", 320, 240, 1, nullptr, vs);
        single.write(rendered[k]);
        single.finish();
        const DecodedVideo one = decode_video(dir / "single.mp4", true);
        ASSERT_EQ(one.frames.size(), 1u);
        EXPECT_EQ(one.frames[0].rgb, sequence.frames[k].rgb);
    }
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
