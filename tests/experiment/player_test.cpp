// The player's window-free parts: the transport's audio clock and frame
// choice, the pitch-preserving time-stretch, play scripts, and the viseme
// editor's state (round trip, undo, phone mapping, diff with the disk), and
// a stimulus definition's poses through its condition's animation layers.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include <unistd.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/experiment/play_media.h"
#include "avsi/experiment/player.h"
#include "avsi/experiment/viseme_editor.h"
#include "avsi/stimuli/head.h"
#include "support/heads.h"
#include "support/layers_protocol.h"
#include "support/temp_dir.h"

namespace avsi::experiment {
namespace {

namespace fs = std::filesystem;

std::vector<float> tone(double hz, int rate, double seconds) {
    std::vector<float> out(static_cast<std::size_t>(std::lround(rate * seconds)));
    for (std::size_t i = 0; i < out.size(); ++i)
        out[i] = 0.5f * static_cast<float>(std::sin(2.0 * std::numbers::pi * hz * static_cast<double>(i) / rate));
    return out;
}

// Frequency from upward zero crossings over the middle half (away from the edges).
double zero_crossing_hz(const std::vector<float>& x, int rate) {
    const std::size_t a = x.size() / 4, b = 3 * x.size() / 4;
    int crossings = 0;
    for (std::size_t i = a + 1; i < b; ++i)
        if (x[i - 1] < 0.0f && x[i] >= 0.0f) ++crossings;
    return crossings / (static_cast<double>(b - a) / rate);
}

TEST(Transport, FrameFollowsTheAudioClockAtEachSpeed) {
    const int rate = 48000;
    const double fps = 30.0;
    const int frames = 45;  // 1.5 s
    for (const double speed : {1.0, 0.5, 0.25}) {
        SCOPED_TRACE(speed);
        Transport t(std::vector<float>(static_cast<std::size_t>(rate * 1.5), 0.1f), rate, fps, frames);
        t.set_speed(speed);
        t.play();
        std::vector<float> buffer(700);  // not a divisor of a frame's samples
        int last = -1;
        while (!t.at_end()) {
            const double media = static_cast<double>(t.samples_played()) * speed / rate;
            const int k = t.frame(0.0);
            EXPECT_EQ(k, std::min(frames - 1, static_cast<int>(std::floor(media * fps + 1e-9))));
            EXPECT_GE(k, last);
            EXPECT_LE(k - last, 1) << "a frame was skipped";
            last = k;
            t.pull(buffer.data(), buffer.size());
        }
        EXPECT_EQ(last, frames - 1);
        EXPECT_EQ(t.samples_played(), std::llround(rate * 1.5 / speed));
    }
}

TEST(Transport, OffsetDelaysTheVideoAndPauseStopsTheClock) {
    Transport t(std::vector<float>(48000, 0.0f), 48000, 30.0, 30);
    t.play();
    std::vector<float> buffer(4800);  // 0.1 s
    t.pull(buffer.data(), buffer.size());
    EXPECT_EQ(t.frame(0.0), 3);
    EXPECT_EQ(t.frame(50.0), 1);    // video 50 ms later: frame of 0.05 s
    EXPECT_EQ(t.frame(-50.0), 4);   // earlier: 0.15 s
    t.pause();
    t.pull(buffer.data(), buffer.size());
    EXPECT_EQ(t.frame(0.0), 3);
    EXPECT_EQ(t.samples_sent(), 9600);
    EXPECT_EQ(t.samples_played(), 4800);
    for (float v : buffer) EXPECT_EQ(v, 0.0f);
}

TEST(Transport, StepsLandOnTheFrameBothWays) {
    Transport t(std::vector<float>(48000, 0.0f), 48000, 30.0, 30);
    t.seek_frame(10);
    EXPECT_EQ(t.frame(0.0), 10);
    t.seek_frame(t.frame(0.0) + 1);
    EXPECT_EQ(t.frame(0.0), 11);
    t.seek_frame(t.frame(0.0) - 2);
    EXPECT_EQ(t.frame(0.0), 9);
    t.set_speed(0.5);  // the media time is kept
    EXPECT_EQ(t.frame(0.0), 9);
    t.seek_frame(-5);
    EXPECT_EQ(t.frame(0.0), 0);
    t.seek_frame(500);
    EXPECT_EQ(t.frame(0.0), 29);
    // With an A/V offset a step still lands on the frame asked for (the audio
    // is moved by the offset): the video 100 ms = 3 frames later.
    t.seek_frame(10, 100.0);
    EXPECT_EQ(t.frame(100.0), 10);
    EXPECT_EQ(t.frame(0.0), 13);
    t.seek_frame(t.frame(100.0) + 1, 100.0);
    EXPECT_EQ(t.frame(100.0), 11);
    EXPECT_NEAR(t.media_time_s(), 11.5 / 30.0 + 0.1, 1e-9);
}

TEST(Transport, PlaysTheAudioUnchangedAtFullSpeed) {
    const auto audio = tone(300.0, 16000, 0.5);
    Transport t(audio, 16000, 25.0, 13);
    t.keep_sent(true);
    t.play();
    std::vector<float> buffer(1000);
    while (!t.at_end()) t.pull(buffer.data(), buffer.size());
    const auto sent = t.sent();
    ASSERT_GE(sent.size(), audio.size());
    for (std::size_t i = 0; i < audio.size(); ++i) ASSERT_EQ(sent[i], audio[i]) << i;
}

TEST(TimeStretch, KeepsThePitchAndTheExactLength) {
    const int rate = 22050;
    const auto audio = tone(440.0, rate, 1.0);
    for (const double speed : {0.25, 0.5, 0.75}) {
        SCOPED_TRACE(speed);
        const auto out = time_stretch(audio, rate, speed);
        EXPECT_EQ(out.size(), static_cast<std::size_t>(std::llround(audio.size() / speed)));
        // Resampling would give 440·speed Hz; WSOLA keeps 440 Hz.
        EXPECT_NEAR(zero_crossing_hz(out, rate), 440.0, 440.0 * 0.02);
    }
    EXPECT_EQ(time_stretch(audio, rate, 1.0), audio);
}

TEST(PlayScript, ReadsCommandsAndRefusesBadLinesWithFileAndLine) {
    const fs::path dir = test::temp_dir("play_script");
    write_text_file(dir / "ok.txt", "# a comment\nspeed 0.5\nplay\n\nwait-end   # to the end\nstep -3\nquit\n");
    const auto events = read_play_script(dir / "ok.txt", false);
    ASSERT_EQ(events.size(), 5u);
    EXPECT_EQ(events[0].command, "speed");
    EXPECT_EQ(events[0].args, std::vector<std::string>{"0.5"});
    EXPECT_EQ(events[0].line, 2);
    EXPECT_EQ(events[3].command, "step");
    EXPECT_EQ(events[4].line, 7);

    write_text_file(dir / "bad.txt", "play\nspede 0.5\nspeed 2\nset jaw_rotation 1\n");
    try {
        read_play_script(dir / "bad.txt", false);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        const std::string text = e.what();
        EXPECT_NE(text.find("bad.txt:2:1: error: command"), std::string::npos) << text;
        EXPECT_NE(text.find("did you mean \"speed\""), std::string::npos) << text;
        EXPECT_NE(text.find("bad.txt:3:1: error: speed"), std::string::npos) << text;
        EXPECT_NE(text.find("bad.txt:4:1: error: command"), std::string::npos) << text;  // editor only
    }
    write_text_file(dir / "edit.txt", "select p_b_m\nset jaw_rotaton 0.3\nsave\n");
    try {
        read_play_script(dir / "edit.txt", true);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("edit.txt:2:1: error: set"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("jaw_rotation"), std::string::npos) << e.what();
    }
}

fs::path copy_set(const fs::path& dir) {
    const fs::path path = dir / "set.json";
    fs::copy_file(fs::path(AVSI_PROTOCOLS_DIR) / "visemes" / "mpeg4_14.json", path, fs::copy_options::overwrite_existing);
    return path;
}

TEST(VisemeEditor, SavesTheSetTheModelReadsAndRoundTrips) {
    const fs::path dir = test::temp_dir("viseme_roundtrip");
    const fs::path path = copy_set(dir);
    VisemeEditor editor(path);
    EXPECT_FALSE(editor.modified());
    EXPECT_TRUE(editor.diff_with_disk().empty());
    editor.save(dir / "again.json");
    const auto original = synth::load_viseme_set(path);
    const auto again = synth::load_viseme_set(dir / "again.json");
    EXPECT_TRUE(viseme_set_diff(original, again).empty());
    // Saving what was read gives the file's bytes back (same schema and key order).
    EXPECT_EQ(read_text_file(dir / "again.json"), read_text_file(path));
}

TEST(VisemeEditor, EditsUndoMappingAndDiffWithTheDisk) {
    const fs::path dir = test::temp_dir("viseme_edit");
    const fs::path path = copy_set(dir);
    VisemeEditor editor(path);
    const std::size_t bilabial = editor.index_of("p_b_m");
    editor.select("p_b_m");
    const double before = editor.selected_viseme().targets[synth::index(synth::Param::JawRotation)];
    const auto alphas_before = editor.alphas();
    editor.begin_edit();
    editor.set_target(synth::Param::JawRotation, 0.3);
    editor.begin_edit();
    editor.set_height_mm(editor.selected_viseme().height_mm * 2.0);
    EXPECT_GT(editor.alphas()[bilabial], alphas_before[bilabial]);  // α follows the ellipse area
    EXPECT_TRUE(editor.modified());
    auto diff = editor.diff_with_disk();
    ASSERT_EQ(diff.size(), 2u);
    EXPECT_NE(diff[0].find("p_b_m.height_mm"), std::string::npos) << diff[0];
    EXPECT_NE(diff[1].find("p_b_m.targets.jaw_rotation"), std::string::npos) << diff[1];
    ASSERT_TRUE(editor.undo());
    EXPECT_EQ(editor.alphas(), alphas_before);
    EXPECT_EQ(editor.diff_with_disk().size(), 1u);
    // Phones move between visemes.
    const std::size_t aa = editor.set().phone_to_viseme.at("AA");
    editor.begin_edit();
    editor.map_phone("AA", bilabial);
    EXPECT_EQ(editor.set().phone_to_viseme.at("AA"), bilabial);
    EXPECT_EQ(std::count(editor.set().visemes[aa].phones.begin(), editor.set().visemes[aa].phones.end(), "AA"), 0);
    EXPECT_THROW(editor.map_phone("XX", bilabial), UsageError);
    EXPECT_THROW(editor.set_target(synth::Param::JawRotation, 99.0), UsageError);
    EXPECT_THROW(editor.select("nope"), UsageError);
    editor.save();
    EXPECT_FALSE(editor.modified());
    EXPECT_TRUE(editor.diff_with_disk().empty());
    const auto saved = synth::load_viseme_set(path);
    EXPECT_EQ(saved.visemes[bilabial].targets[synth::index(synth::Param::JawRotation)], 0.3);
    EXPECT_EQ(saved.phone_to_viseme.at("AA"), bilabial);
    ASSERT_TRUE(editor.undo());
    ASSERT_TRUE(editor.undo());
    EXPECT_EQ(editor.selected_viseme().targets[synth::index(synth::Param::JawRotation)], before);
    EXPECT_FALSE(editor.undo());
}

TEST(VisemeEditor, RefusesABadSetWithFileAndField) {
    const fs::path dir = test::temp_dir("viseme_bad");
    std::string text = read_text_file(fs::path(AVSI_PROTOCOLS_DIR) / "visemes" / "mpeg4_14.json");
    text.replace(text.find("\"width_mm\": "), 12, "\"width_mm\": -");
    write_text_file(dir / "bad.json", text);
    try {
        VisemeEditor editor(dir / "bad.json");
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("bad.json:"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("width_mm"), std::string::npos) << e.what();
    }
    write_text_file(dir / "syntax.json", "{\"name\": \"x\",\n \"visemes\": [\n");
    EXPECT_THROW(VisemeEditor(dir / "syntax.json"), InputError);
    EXPECT_THROW(VisemeEditor(dir / "missing.json"), InputError);
}

// A stimulus definition plays with its condition's animation layers, as the
// builder renders it: an expressive condition turns the head and raises the
// brows, its mouth still the speech layer's; a plain condition of the same
// protocol is speech and blinks only, frame for frame its trajectory.
TEST(PlayMedia, AStimulusDefinitionPlaysItsConditionsLayers) {
    const fs::path dir = test::temp_dir("play_layers");
    test::write_layers_protocol(dir / "p.toml", "play-layers",
                                "[condition.layers]\nexpression = \"surprised\"\nhead_motion = \"idle\"\ngaze = true\n");
    const stimuli::Head& head = test::default_head();
    auto played = [&](const std::string& condition) {
        PlaySource source;
        source.protocol_path = dir / "p.toml";
        source.sentence = "s1";
        source.condition = condition;
        PlayMedia m = load_play_media(source);
        animate_play_media(head, m);
        return m;
    };
    const PlayMedia expressive = played("expressive");
    const PlayMedia plain = played("plain");
    ASSERT_EQ(expressive.poses.size(), expressive.trajectory.size());
    ASSERT_EQ(plain.poses.size(), plain.trajectory.size());
    ASSERT_GT(plain.poses.size(), 30u);

    std::size_t turned = 0, raised = 0;
    for (std::size_t k = 0; k < expressive.poses.size(); ++k) {
        const stimuli::Pose& pose = expressive.poses[k];
        turned += !pose.head_at_rest();
        raised += pose.brow_inner_raise > 0.05 || pose.brow_outer_raise > 0.05;
        // The speech layer owns the mouth: the jaw and lips are the trajectory's.
        for (std::size_t c = 0; c < synth::param_count; ++c)
            EXPECT_EQ(pose.params[c], expressive.trajectory.frames[k][c]) << "frame " << k << " parameter " << c;
    }
    EXPECT_GT(turned, expressive.poses.size() / 2);
    EXPECT_EQ(raised, expressive.poses.size());

    for (std::size_t k = 0; k < plain.poses.size(); ++k) {
        const stimuli::Pose& pose = plain.poses[k];
        EXPECT_TRUE(pose.head_at_rest() && pose.expression_at_rest()) << "frame " << k;
        EXPECT_EQ(pose.gaze_left, 0.0);
        for (std::size_t c = 0; c < synth::param_count; ++c) EXPECT_EQ(pose.params[c], plain.trajectory.frames[k][c]);
    }
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi::experiment
