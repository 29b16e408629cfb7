#include "avsi/experiment/media.h"

#include <gtest/gtest.h>

#include <cmath>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/experiment/runner.h"
#include "support/temp_dir.h"

namespace avsi::experiment {
namespace {

// Presents a clip against the null device's simulated clock the way the
// runner does: the frame for each flip chosen on the audio clock.
Presentation present(double fps, double refresh_hz, int skip_flip = -1) {
    TestPatternSettings s;
    s.fps = fps;
    s.width = 16;
    s.height = 8;
    auto clip = make_test_pattern(s);
    NullAudioOutput audio;
    const double period = 1.0 / refresh_hz;
    audio.after_flip(period * 7);  // some time has passed
    FramePacer pacer(fps, clip->frame_count(), refresh_hz);
    double next_flip = audio.now_s() + period;
    audio.play(clip->audio(), clip->sample_rate(), next_flip);
    pacer.start(*audio.onset_s());
    VideoFrame frame;
    bool have = false;
    for (int flip = 0; flip < 10000; ++flip) {
        next_flip = audio.now_s() + period;
        const int k = pacer.frame_for(next_flip);
        if (k >= clip->frame_count()) break;
        while ((!have || frame.index < k) && clip->next_frame(frame)) have = true;
        audio.after_flip(period);
        if (flip == skip_flip) continue;  // the swap missed: nothing new reached the screen
        pacer.flipped(k, frame.pts_s, audio.now_s());
    }
    EXPECT_TRUE(audio.playing());  // the last frame's flip is the clip's last period
    audio.after_flip(period);
    EXPECT_FALSE(audio.playing());
    return pacer.summary();
}

TEST(FramePacer, NoDroppedFramesAndZeroOffsetAt60HzOnTheSimulatedClock) {
    const Presentation p = present(30.0, 60.0);
    EXPECT_EQ(p.frames_total, 30);
    EXPECT_EQ(p.frames_shown, 30);
    EXPECT_EQ(p.dropped_frames, 0);
    EXPECT_EQ(p.repeated_frames, 0);
    EXPECT_LE(p.max_abs_offset_ms, 1.0);
    EXPECT_LT(p.max_abs_offset_ms, 1e-6);
}

TEST(FramePacer, TwentyFiveFpsAt60HzShowsEveryFrameWithinHalfAFlip) {
    const Presentation p = present(25.0, 60.0);
    EXPECT_EQ(p.dropped_frames, 0);
    EXPECT_EQ(p.repeated_frames, 0);
    EXPECT_LE(p.max_abs_offset_ms, 1000.0 / 60.0);
}

TEST(FramePacer, AMissedFlipAt30HzDropsAFrame) {
    const Presentation p = present(30.0, 30.0, 5);
    EXPECT_EQ(p.dropped_frames, 1);
    EXPECT_EQ(p.frames_shown, 29);
}

TEST(TestPattern, EncodesTheFrameIndexAndClicksAtFrameOnsets) {
    TestPatternSettings s;
    s.width = 64;
    s.height = 40;
    auto clip = make_test_pattern(s);
    VideoFrame f;
    for (int k = 0; k <= 5; ++k) ASSERT_TRUE(clip->next_frame(f));
    EXPECT_EQ(f.index, 5);
    // Blocks 0..7 along the top carry bits 7..0: 5 = 00000101.
    auto block = [&](int b) { return f.rgba[static_cast<std::size_t>(b * 8 + 4) * 4]; };
    EXPECT_EQ(block(7), 255);
    EXPECT_EQ(block(6), 0);
    EXPECT_EQ(block(5), 255);
    EXPECT_EQ(block(0), 0);
    const auto& audio = clip->audio();
    const auto onset = static_cast<std::size_t>(std::lround(5 / s.fps * s.sample_rate));
    EXPECT_GT(std::fabs(audio[onset + 5]), 0.01f);
    EXPECT_EQ(audio[onset - 10], 0.0f);
}

// A stimulus folder must carry the builder's manifest; its entries are read
// by path and a folder without one is refused with the command that makes it.
TEST(StimulusManifest, ReadsEntriesAndRefusesAFolderWithoutOne) {
    const auto dir = test::temp_dir("manifest");
    try {
        read_stimulus_manifest(dir);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("avsi build-stimuli"), std::string::npos) << e.what();
    }
    write_text_file(dir / "manifest.json", R"({"format": "something-else", "stimuli": []})");
    EXPECT_THROW(read_stimulus_manifest(dir), InputError);
    write_text_file(dir / "manifest.json",
                    R"({"format": "avsi-stimuli-manifest", "experiment": "e", "stimuli": [
                        {"path": "s1/a.mp4", "frames": 39, "fps": 30.0, "sha256": "ab"},
                        {"path": "s1/b.mp4", "fps": 30.0, "sha256": "cd"}]})");
    try {
        read_stimulus_manifest(dir);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("stimuli[1]"), std::string::npos) << e.what();
    }
    write_text_file(dir / "manifest.json",
                    R"({"format": "avsi-stimuli-manifest", "experiment": "e", "stimuli": [
                        {"path": "s1/a.mp4", "frames": 39, "fps": 30.0, "sha256": "ab"}]})");
    const StimulusManifest m = read_stimulus_manifest(dir);
    EXPECT_EQ(m.experiment, "e");
    ASSERT_EQ(m.stimuli.count("s1/a.mp4"), 1u);
    EXPECT_EQ(m.stimuli.at("s1/a.mp4").frames, 39);
    EXPECT_EQ(m.sha256, sha256_file(dir / "manifest.json"));
    // Listed but absent on disk: refused before anything is shown.
    StimulusFolderOpener opener(dir);
    EXPECT_THROW(opener.verify({"s1/a.mp4"}), InputError);
    EXPECT_THROW(opener.verify({"s2/a.mp4"}), InputError);
}

}  // namespace
}  // namespace avsi::experiment
