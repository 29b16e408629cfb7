// `avsi play` end to end under a private Xvfb server with the null audio
// device (simulated clock): a stimulus definition played at 1× and 0.5× is
// frame-accurate against the stimulus (every frame in order, frame k shown
// while the audio time is in [k/fps, (k+1)/fps), the pose shown is frame k's,
// the audio samples played are duration/speed), frame steps both ways, a
// recording, and the viseme editor's scripted change saved to a set that the
// MPEG-4 Cohen-Massaro model then uses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "avsi/core/audio.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/phones.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/video.h"
#include "avsi/synth/cohen_massaro.h"
#include "avsi/synth/mpeg4_cohen_massaro.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"
#include "support/xvfb.h"

namespace avsi::experiment {
namespace {

namespace fs = std::filesystem;
using test::run_avsi_logged;

const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build" / "protocol.toml";

// One Xvfb server for the suite; DISPLAY points at it.
class PlayE2E : public ::testing::Test {
protected:
    static void SetUpTestSuite() { s_xvfb = test::start_xvfb(); }
    static void TearDownTestSuite() { test::stop_xvfb(s_xvfb); }
    void SetUp() override {
        if (s_xvfb <= 0) GTEST_SKIP() << "Xvfb is not available";
    }
    static inline pid_t s_xvfb = -1;
};

struct LogRow {
    int frame = 0;
    long long sent = 0;
    long long played = 0;
    double speed = 1.0;
    double offset_ms = 0.0;
    double media_s = 0.0;
    bool playing = false;
    synth::Frame params{};
};

std::vector<LogRow> read_log(const fs::path& path) {
    std::ifstream in(path);
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line.rfind("refresh\twall_s\tframe\tsamples_sent\tsamples_played\tmedia_s\tspeed\toffset_ms\tplaying", 0), 0u);
    std::vector<LogRow> rows;
    while (std::getline(in, line)) {
        std::istringstream s(line);
        LogRow r;
        int refresh = 0, playing = 0;
        double wall = 0;
        s >> refresh >> wall >> r.frame >> r.sent >> r.played >> r.media_s >> r.speed >> r.offset_ms >> playing;
        r.playing = playing != 0;
        for (auto& v : r.params) s >> v;
        EXPECT_TRUE(s) << line;
        rows.push_back(r);
    }
    return rows;
}

// The stimulus as the player must show it: trajectory frames and the audio
// fitted to the video's length.
struct Reference {
    synth::Trajectory trajectory;
    std::size_t audio_samples = 0;
    int rate = 0;
    std::vector<float> audio;  // the stimulus's audio (mono)
};

const Reference& reference() {
    static const Reference r = [] {
        const auto d = stimuli::stimulus_definition(protocol, "s1", "rule");
        Reference out;
        out.trajectory = d.trajectory;
        out.rate = d.audio.sample_rate_hz;
        out.audio = d.audio.mono();
        out.audio_samples =
            static_cast<std::size_t>(std::llround(d.trajectory.size() / d.trajectory.fps * d.audio.sample_rate_hz));
        return out;
    }();
    return r;
}

TEST_F(PlayE2E, PlaysAStimulusFrameAccurateAtFullAndHalfSpeed) {
    const fs::path dir = test::temp_dir("play_speeds");
    const Reference& ref = reference();
    const int frames = static_cast<int>(ref.trajectory.size());
    const double fps = ref.trajectory.fps;
    ASSERT_GT(frames, 20);
    for (const double speed : {1.0, 0.5}) {
        SCOPED_TRACE(speed);
        const std::string tag = speed == 1.0 ? "full" : "half";
        write_text_file(dir / (tag + ".txt"), fmt::format("speed {}\nplay\nwait-end\nwait 2\nquit\n", speed));
        std::vector<std::string> args = {"play", "--protocol", protocol.string(), "--sentence", "s1", "--condition",
                                         "rule", "--audio", "null", "--size", "640x400", "--script",
                                         (dir / (tag + ".txt")).string(), "--log", (dir / (tag + ".tsv")).string(),
                                         "--audio-out", (dir / (tag + ".wav")).string()};
        if (speed == 1.0) {
            args.push_back("--record");
            args.push_back((dir / "full.mp4").string());
        }
        ASSERT_EQ(run_avsi_logged(args, dir / (tag + ".log")), 0) << read_text_file(dir / (tag + ".log"));
        const auto rows = read_log(dir / (tag + ".tsv"));
        ASSERT_FALSE(rows.empty());
        int last = -1;
        std::vector<int> seen(static_cast<std::size_t>(frames), 0);
        for (const auto& r : rows) {
            if (!r.playing) continue;
            EXPECT_EQ(r.speed, speed);
            // Frame k while the audio time is in [k/fps, (k+1)/fps).
            const double t = static_cast<double>(r.played) * speed / ref.rate;
            EXPECT_LE(r.frame / fps, t + 1e-9);
            EXPECT_LT(t, (r.frame + 1) / fps + 1e-9);
            // In order, none skipped.
            EXPECT_GE(r.frame, last);
            EXPECT_LE(r.frame - last, 1);
            last = r.frame;
            seen[static_cast<std::size_t>(r.frame)] = 1;
            // The pose shown is that frame of the stimulus's trajectory.
            for (std::size_t q = 0; q < synth::param_count; ++q)
                ASSERT_NEAR(r.params[q], ref.trajectory.frames[static_cast<std::size_t>(r.frame)][q], 1e-7)
                    << "frame " << r.frame << " parameter " << q;
        }
        for (int k = 0; k < frames; ++k) EXPECT_TRUE(seen[static_cast<std::size_t>(k)]) << "frame " << k << " never shown";
        // The audio played lasts duration / speed; what was sent is that plus
        // the silence of the refreshes after the end.
        const auto expected = std::llround(static_cast<double>(ref.audio_samples) / speed);
        EXPECT_EQ(rows.back().played, expected);
        const Audio sent = read_audio(dir / (tag + ".wav"));
        EXPECT_EQ(sent.sample_rate_hz, ref.rate);
        EXPECT_GE(static_cast<long long>(sent.frames()), expected);
        EXPECT_LE(static_cast<long long>(sent.frames()), expected + 4 * ref.rate / 60 + 1);
        double energy = 0.0;
        for (float v : sent.samples) energy += static_cast<double>(v) * v;
        EXPECT_GT(energy, 0.0);
        if (speed == 1.0) {
            // At 1x the device got the stimulus's own samples (through a 16-bit WAV).
            const std::size_t n = std::min(ref.audio.size(), ref.audio_samples);
            ASSERT_GE(sent.samples.size(), n);
            for (std::size_t i = 0; i < n; ++i)
                ASSERT_NEAR(sent.samples[i], ref.audio[i], 1.0 / 32767.0) << "sample " << i;
        }
    }
    // The recording: the window at the stimulus's frame rate with the audio sent.
    const auto video = stimuli::decode_video(dir / "full.mp4");
    EXPECT_GE(static_cast<int>(video.frame_count), frames);
    EXPECT_LE(static_cast<int>(video.frame_count), frames + 3);
    EXPECT_TRUE(video.has_audio);
}

TEST_F(PlayE2E, StepsFramesBothWaysAndAppliesTheOffset) {
    const fs::path dir = test::temp_dir("play_steps");
    write_text_file(dir / "steps.txt", "seek 10\nwait 1\nstep 1\nwait 1\nstep -3\nwait 1\noffset 100\nseek 12\nwait 1\n"
                                       "step 1\nwait 1\nplay\nwait 3\nquit\n");
    ASSERT_EQ(run_avsi_logged({"play", "--protocol", protocol.string(), "--sentence", "s1", "--condition", "rule", "--audio", "null",
                   "--size", "640x400", "--script", (dir / "steps.txt").string(), "--log", (dir / "log.tsv").string()},
                  dir / "out.log"),
              0)
        << read_text_file(dir / "out.log");
    const auto rows = read_log(dir / "log.tsv");
    ASSERT_GE(rows.size(), 8u);
    EXPECT_EQ(rows[0].frame, 10);
    EXPECT_EQ(rows[1].frame, 11);
    EXPECT_EQ(rows[2].frame, 8);
    // With the video 100 ms later, seek 12 shows frame 12 with the audio
    // 100 ms further on (frame 12's middle + 0.1 s), and a step goes forward.
    EXPECT_EQ(rows[3].offset_ms, 100.0);
    EXPECT_EQ(rows[3].frame, 12);
    EXPECT_NEAR(rows[3].media_s, 12.5 / 30.0 + 0.1, 1e-5);
    EXPECT_EQ(rows[4].frame, 13);
    // Playing on from there: the frame follows the audio clock less the offset.
    for (std::size_t i = 5; i < rows.size(); ++i) {
        if (!rows[i].playing) continue;
        const double x = (rows[i].media_s - 0.1) * 30.0;  // media_s is logged to 1 µs
        EXPECT_TRUE(rows[i].frame == static_cast<int>(std::floor(x + 1e-4)) ||
                    rows[i].frame == static_cast<int>(std::floor(x - 1e-4)))
            << "row " << i << ": frame " << rows[i].frame << " at media time " << rows[i].media_s;
    }
}

TEST_F(PlayE2E, RefusesBadInputsWithFileAndField) {
    const fs::path dir = test::temp_dir("play_bad");
    write_text_file(dir / "bad.txt", "play\nsped 0.5\n");
    EXPECT_EQ(run_avsi_logged({"play", "--protocol", protocol.string(), "--sentence", "s1", "--condition", "rule", "--audio", "null",
                   "--script", (dir / "bad.txt").string()},
                  dir / "script.log"),
              1);
    EXPECT_NE(read_text_file(dir / "script.log").find("bad.txt:2:1: error: command"), std::string::npos)
        << read_text_file(dir / "script.log");
    EXPECT_EQ(run_avsi_logged({"play", "--protocol", protocol.string(), "--sentence", "s9", "--condition", "rule", "--audio", "null"},
                  dir / "sentence.log"),
              1);
    EXPECT_NE(read_text_file(dir / "sentence.log").find("error: id: expected a sentence id"), std::string::npos)
        << read_text_file(dir / "sentence.log");
    write_text_file(dir / "set.json", "{\"name\": \"x\", \"visemes\": [}\n");
    EXPECT_EQ(run_avsi_logged({"play", "--edit-visemes", (dir / "set.json").string(), "--audio", "null"}, dir / "set.log"), 1);
    EXPECT_NE(read_text_file(dir / "set.log").find("set.json:1:"), std::string::npos) << read_text_file(dir / "set.log");
    EXPECT_EQ(run_avsi_logged({"play", "--traj", (dir / "missing.csv").string(), "--audio", "null"}, dir / "missing.log"), 2);
}

TEST_F(PlayE2E, PlaysABuiltStimulusWithItsWavAndRefusesAChangedOne) {
    const fs::path dir = test::temp_dir("play_built");
    ASSERT_EQ(run_avsi_logged({"build-stimuli", protocol.string(), "--out", (dir / "built").string()}, dir / "build.log"), 0)
        << read_text_file(dir / "build.log");
    write_text_file(dir / "play.txt", "play\nwait-end\nquit\n");
    const std::vector<std::string> args = {"play", "--protocol", protocol.string(), "--stimuli", (dir / "built").string(),
                                           "--stimulus", "s2/rule.mp4", "--audio", "null", "--size", "640x400",
                                           "--script", (dir / "play.txt").string(), "--audio-out",
                                           (dir / "sent.wav").string()};
    ASSERT_EQ(run_avsi_logged(args, dir / "play.log"), 0) << read_text_file(dir / "play.log");
    const Audio built = read_audio(dir / "built" / "s2" / "rule.wav");
    const Audio sent = read_audio(dir / "sent.wav");
    ASSERT_GE(sent.samples.size(), built.samples.size());
    for (std::size_t i = 0; i < built.samples.size(); ++i) ASSERT_EQ(sent.samples[i], built.samples[i]) << i;
    // The stimulus definition is what the builder built: the same audio (up
    // to the WAV's 16 bits) and the manifest's frame count.
    const auto definition = stimuli::stimulus_definition(protocol, "s2", "rule");
    ASSERT_EQ(definition.audio.samples.size(), built.samples.size());
    for (std::size_t i = 0; i < built.samples.size(); ++i)
        ASSERT_NEAR(definition.audio.samples[i], built.samples[i], 1.0 / 32767.0) << i;
    const auto manifest = read_json_file(dir / "built" / "manifest.json");
    int entries = 0;
    for (const auto& e : manifest.at("stimuli"))
        if (e.at("path") == "s2/rule.mp4") {
            ++entries;
            EXPECT_EQ(e.at("frames").get<std::size_t>(), definition.trajectory.size());
        }
    EXPECT_EQ(entries, 1);
    // A WAV changed after the build is refused, naming it and the manifest's hash.
    Audio changed = built;
    changed.samples[100] += 0.25f;
    write_audio(dir / "built" / "s2" / "rule.wav", changed);
    EXPECT_EQ(run_avsi_logged(args, dir / "changed.log"), 1);
    EXPECT_NE(read_text_file(dir / "changed.log").find("rule.wav: error: wav_sha256: expected"), std::string::npos)
        << read_text_file(dir / "changed.log");
}

// Σ_{i∈v} D_i(t) / Σ_i D_i(t): the share of viseme v's segments in eq. 7 at t.
double share_of(const std::vector<synth::CmSegment>& segments, const std::vector<bool>& of_viseme, double t) {
    double all = 0.0, mine = 0.0;
    for (std::size_t i = 0; i < segments.size(); ++i) {
        const double d = synth::dominance(segments[i], t);
        all += d;
        if (of_viseme[i]) mine += d;
    }
    return mine / all;
}

TEST_F(PlayE2E, EditorChangeIsWhatTheMpeg4ModelThenUses) {
    const fs::path dir = test::temp_dir("play_editor");
    const fs::path original = fs::path(AVSI_PROTOCOLS_DIR) / "visemes" / "mpeg4_14.json";
    fs::copy_file(original, dir / "set.json");
    write_text_file(dir / "edit.txt", "select p_b_m\nset jaw_rotation 0.35\nwait 1\nsave\nquit\n");
    ASSERT_EQ(run_avsi_logged({"play", "--edit-visemes", (dir / "set.json").string(), "--audio", "null", "--size", "800x560",
                   "--script", (dir / "edit.txt").string()},
                  dir / "edit.log"),
              0)
        << read_text_file(dir / "edit.log");
    const synth::VisemeSet before = synth::load_viseme_set(original);
    const synth::VisemeSet after = synth::load_viseme_set(dir / "set.json");
    std::size_t v = 0;
    while (before.visemes[v].name != "p_b_m") ++v;
    const auto jaw = synth::index(synth::Param::JawRotation);
    EXPECT_EQ(after.visemes[v].targets[jaw], 0.35);
    const double delta = 0.35 - before.visemes[v].targets[jaw];
    ASSERT_NE(delta, 0.0);

    // "Bob wore a blue wool coat": B twice, as a bilabial viseme.
    const PhoneSequence phones = {{"sil", 0.0, 0.10},  {"B", 0.10, 0.18},  {"AA", 0.18, 0.30}, {"B", 0.30, 0.38},
                                  {"W", 0.38, 0.46},   {"AO", 0.46, 0.60}, {"R", 0.60, 0.68}, {"sil", 0.68, 1.00}};
    const synth::Mpeg4CohenMassaroModel model_before(before, "before.json", {});
    const synth::Mpeg4CohenMassaroModel model_after(after, "set.json", {});
    const double fps = 100.0;
    const auto a = model_before.synthesize(phones, fps);
    const auto b = model_after.synthesize(phones, fps);
    ASSERT_EQ(a.size(), b.size());
    const auto segments = model_after.segments_all(phones)[jaw];
    std::vector<bool> of_viseme;
    for (const auto& p : phones) of_viseme.push_back(after.phone_to_viseme.at(p.symbol) == v);
    ASSERT_EQ(segments.size(), phones.size());
    double largest_share = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        const double t = a.time_s(k);
        // Only the jaw changes, by Δ·(p_b_m's share of the dominance): where
        // the viseme is used it moves to the new target, elsewhere it hardly does.
        for (std::size_t q = 0; q < synth::param_count; ++q) {
            if (q != jaw) {
                ASSERT_EQ(a.frames[k][q], b.frames[k][q]) << "frame " << k << " parameter " << q;
            }
        }
        const double share = share_of(segments, of_viseme, t);
        EXPECT_NEAR(b.frames[k][jaw] - a.frames[k][jaw], delta * share, 1e-6) << "frame " << k;
        largest_share = std::max(largest_share, share);
        const bool inside_b = (t >= 0.10 && t < 0.18) || (t >= 0.30 && t < 0.38);
        if (!inside_b && (t < 0.05 || t > 0.55)) {
            EXPECT_LT(std::fabs(b.frames[k][jaw] - a.frames[k][jaw]), 0.25 * std::fabs(delta)) << "frame " << k;
        }
    }
    EXPECT_GT(largest_share, 0.5);  // at the B centres the edited target dominates
}

}  // namespace
}  // namespace avsi::experiment
