// End-to-end runs of `avsi run` / `avsi export` under a private Xvfb server
// with the null audio device (simulated clock): scripted sessions, SIGKILL
// crash safety with resume, and screenshots.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <chrono>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>
#include <algorithm>
#include <cmath>

#include "avsi/analysis/adaptive.h"
#include "avsi/core/audio.h"
#include "avsi/core/csv.h"
#include "avsi/core/rng.h"
#include "avsi/experiment/adaptive_session.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/media.h"
#include "avsi/experiment/runner.h"
#include "avsi/experiment/store.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/image_io.h"
#include "avsi/stimuli/video.h"
#include "avsi/vocoder/masking.h"
#include "support/generated_study.h"
#include "support/run_avsi.h"
#include "support/sqlite_count.h"
#include "support/temp_dir.h"
#include "support/xvfb.h"

namespace avsi::experiment {
namespace {

using test::count_rows;
using test::GeneratedStudy;
using test::run_avsi_logged;
using test::start_avsi;
using test::temp_dir;
using test::write_study;
namespace fs = std::filesystem;

// One Xvfb server for the whole suite; DISPLAY points at it.
class RunnerE2E : public ::testing::Test {
protected:
    static void SetUpTestSuite() { s_xvfb = test::start_xvfb(); }
    static void TearDownTestSuite() { test::stop_xvfb(s_xvfb); }
    void SetUp() override {
        if (s_xvfb <= 0) GTEST_SKIP() << "Xvfb is not available";
    }

    static std::vector<std::string> run_args(const fs::path& protocol, int subject, const fs::path& db,
                                             const fs::path& script) {
        return {"run", protocol.string(), "--subject", std::to_string(subject), "--db", db.string(), "--test-pattern",
                "--audio", "null", "--windowed", "--size", "320x240", "--script", script.string()};
    }
    // One distinct response per planned trial; every 5th empty.
    static fs::path write_script(const fs::path& path, int trials, int subject) {
        std::string text = "# scripted responses\n";
        for (int i = 1; i <= trials; ++i) text += i % 5 == 0 ? "-\n" : fmt::format("answer {} {}\n", subject, i);
        write_text_file(path, text);
        return path;
    }

    // Responses committed so far.
    static int committed(const fs::path& db) { return count_rows(db, "responses"); }

    // Runs the runner once per target, killing it (SIGKILL) as soon as the
    // adaptive presentations stored in `db` reach the target; each run must
    // still have been going (not ended) and stopped mid-track (fewer than
    // `limit` stored). Adds one to `kills` per kill.
    static void kill_at_presentations(const std::vector<std::string>& args, const fs::path& log, const fs::path& db,
                                      std::initializer_list<int> targets, int limit, int& kills) {
        for (const int target : targets) {
            const pid_t pid = start_avsi(args, log);
            const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
            while (count_rows(db, "adaptive_trials") < target && std::chrono::steady_clock::now() < give_up)
                std::this_thread::sleep_for(std::chrono::milliseconds(2));
            ::kill(pid, SIGKILL);
            int status = 0;
            ::waitpid(pid, &status, 0);
            ASSERT_TRUE(WIFSIGNALED(status)) << "the run ended before the kill:\n" << read_text_file(log);
            ++kills;
            const int stored = count_rows(db, "adaptive_trials");
            ASSERT_GE(stored, target);
            ASSERT_LT(stored, limit) << "killed too late to be mid-track";
        }
    }

    static inline pid_t s_xvfb = -1;
};

TEST_F(RunnerE2E, ScriptedSessionsForTwoSubjectsCompleteAndExportEveryResponse) {
    const fs::path dir = temp_dir("e2e_two");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "protocol.toml";
    const fs::path db = dir / "exp.sqlite";
    for (int subject : {1, 2}) {
        const auto script = write_script(dir / fmt::format("s{}.txt", subject), 10, subject);
        ASSERT_EQ(run_avsi_logged(run_args(protocol, subject, db, script), dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    }
    ASSERT_EQ(run_avsi_logged({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), 20u);
    for (std::size_t i = 0; i < responses.rows.size(); ++i) {
        const auto& f = responses.rows[i].fields;
        const int subject = static_cast<int>(i / 10) + 1, trial = static_cast<int>(i % 10) + 1;
        EXPECT_EQ(f[0], std::to_string(subject));
        EXPECT_EQ(f[2], std::to_string(trial));
        EXPECT_EQ(f[7], trial % 5 == 0 ? "" : fmt::format("answer {} {}", subject, trial));
    }
    // The dry run's scoring names the protocol's rule set (strict: no [scoring] table).
    ASSERT_EQ(run_avsi_logged({"score", "--protocol", protocol.string(), "--responses", (dir / "export" / "responses.csv").string(),
                   "--out", (dir / "scores").string()},
                  dir / "log.txt"),
              0)
        << read_text_file(dir / "log.txt");
    const CsvTable scores = read_csv(dir / "scores" / "scores.csv");
    ASSERT_FALSE(scores.rows.empty());
    for (const auto& row : scores.rows) EXPECT_EQ(row.fields[scores.require_column("rule_set")], "strict");
    EXPECT_TRUE(fs::exists(dir / "scores" / "audit.csv"));
    // Timing against the simulated 60 Hz clock: every frame shown, in sync.
    const CsvTable timing = read_csv(dir / "export" / "timing.csv");
    ASSERT_EQ(timing.rows.size(), 20u);
    const auto dropped = timing.require_column("dropped_frames");
    const auto repeated = timing.require_column("repeated_frames");
    const auto offset = timing.require_column("max_abs_av_offset_ms");
    const auto shown = timing.require_column("frames_shown");
    for (const auto& row : timing.rows) {
        EXPECT_EQ(row.fields[dropped], "0");
        EXPECT_EQ(row.fields[repeated], "0");
        EXPECT_EQ(row.fields[shown], "30");
        EXPECT_LE(std::fabs(*parse_double(row.fields[offset])), 1.0);
    }
}

TEST_F(RunnerE2E, SigkillAtRandomPointsThenResumeLosesAndRepeatsNothing) {
    const fs::path dir = temp_dir("e2e_kill");
    GeneratedStudy g;  // 6 conditions × 3 + 2 warm-up + 2 practice = 22 trials
    const fs::path protocol = write_study(dir, g);
    const int trials = 22;
    const fs::path db = dir / "kill.sqlite";
    const auto script = write_script(dir / "script.txt", trials, 1);
    const auto args = run_args(protocol, 1, db, script);
    // The sequence the design gives subject 1, computed here independently of the runner.
    const Protocol p = load_protocol(protocol);
    const std::vector<PlannedTrial> designed = make_design(p, read_corpus(p.corpus.sentences), 1);
    ASSERT_EQ(designed.size(), static_cast<std::size_t>(trials));
    Rng rng(20260);
    SCOPED_TRACE("seed 20260");
    std::vector<int> answered_before;
    int kills = 0;
    bool done = false;
    for (int attempt = 0; attempt < 80 && !done; ++attempt) {
        // Kill at a random point: after one more committed response, then
        // 0–250 ms on (a scripted trial on the simulated clock takes about
        // that long on a slow machine: commit, fixation, stimulus or answer
        // box), but no later than the next commit (a fast machine runs
        // several trials in 250 ms). At least 4 trials are left after the
        // target, and the last runs go to the end unkilled, so a kill never
        // lands after the last commit.
        const bool kill_this = answered_before.size() + 5 <= static_cast<std::size_t>(trials);
        const int target = kill_this ? static_cast<int>(answered_before.size()) + 1 : trials + 1;
        const auto extra = std::chrono::milliseconds(rng.uniform_int(250));
        const pid_t pid = start_avsi(args, dir / "log.txt");
        int status = 0;
        pid_t finished = 0;
        auto deadline = std::chrono::steady_clock::time_point::max();
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
        while ((finished = ::waitpid(pid, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline &&
               std::chrono::steady_clock::now() < give_up) {
            const int n = committed(db);
            if (deadline == std::chrono::steady_clock::time_point::max() && n >= target)
                deadline = std::chrono::steady_clock::now() + extra;
            if (n > target) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
        if (finished == pid) {
            ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read_text_file(dir / "log.txt");
            done = true;
        } else {
            ::kill(pid, SIGKILL);
            ::waitpid(pid, &status, 0);
            ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
            ++kills;
        }
        Store store(db);
        // The stored sequence is the designed one, after every kill.
        EXPECT_EQ(store.planned_trials(1), designed) << "the trial sequence changed after kill " << kills;
        const auto answered = store.answered_positions(1);
        // Nothing committed is lost, and trials are answered in plan order (1..n, no gaps).
        EXPECT_TRUE(std::includes(answered.begin(), answered.end(), answered_before.begin(), answered_before.end()));
        for (std::size_t i = 0; i < answered.size(); ++i) EXPECT_EQ(answered[i], static_cast<int>(i) + 1);
        answered_before = answered;
    }
    ASSERT_TRUE(done) << "the session never completed";
    EXPECT_GE(kills, 8);
    ASSERT_EQ(run_avsi_logged({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), static_cast<std::size_t>(trials));
    std::set<int> positions;
    std::map<int, std::vector<int>> trials_of_session;
    for (const auto& row : responses.rows) {
        const int trial = static_cast<int>(*parse_int(row.fields[2]));
        EXPECT_TRUE(positions.insert(trial).second) << "trial " << trial << " answered twice";
        EXPECT_EQ(row.fields[7], trial % 5 == 0 ? "" : fmt::format("answer 1 {}", trial));
        const PlannedTrial& planned = designed[static_cast<std::size_t>(trial - 1)];
        EXPECT_EQ(row.fields[4], planned.condition);
        EXPECT_EQ(row.fields[6], planned.sentence);
        trials_of_session[static_cast<int>(*parse_int(row.fields[1]))].push_back(trial);
    }
    // One session per run: each killed one recorded as interrupted by the
    // next run, which resumed at the first trial without a response.
    const CsvTable sessions = read_csv(dir / "export" / "sessions.csv");
    ASSERT_EQ(sessions.rows.size(), static_cast<std::size_t>(kills + 1));
    int answered_so_far = 0;
    for (std::size_t i = 0; i < sessions.rows.size(); ++i) {
        const auto& f = sessions.rows[i].fields;
        SCOPED_TRACE("session " + f[1]);
        EXPECT_EQ(f[4], i + 1 < sessions.rows.size() ? "interrupted" : "completed");
        EXPECT_EQ(f[5], std::to_string(answered_so_far + 1));
        const auto& answered = trials_of_session[static_cast<int>(*parse_int(f[1]))];
        for (std::size_t k = 0; k < answered.size(); ++k)
            EXPECT_EQ(answered[k], answered_so_far + 1 + static_cast<int>(k));
        answered_so_far += static_cast<int>(answered.size());
    }
    EXPECT_EQ(answered_so_far, trials);
    std::cerr << "[ info ] " << kills << " kills, " << sessions.rows.size() << " sessions\n";
}

TEST_F(RunnerE2E, ScreenshotsOfEveryScreenKind) {
    const fs::path dir = temp_dir("e2e_shots");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "protocol.toml";
    const auto script = write_script(dir / "s.txt", 10, 1);
    auto args = run_args(protocol, 1, dir / "shots.sqlite", script);
    args.push_back("--screenshots");
    args.push_back((dir / "png").string());
    ASSERT_EQ(run_avsi_logged(args, dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    std::set<std::string> kinds;
    for (const auto& entry : fs::directory_iterator(dir / "png")) {
        const std::string name = entry.path().filename().string();
        kinds.insert(name.substr(5, name.rfind("_trial") - 5));
        EXPECT_GT(fs::file_size(entry.path()), 200u);
    }
    for (const char* kind : {"instructions", "fixation", "trial", "response", "confirm-empty", "feedback", "break", "end"})
        EXPECT_TRUE(kinds.count(kind)) << kind;
}

// The lag (in samples, |lag| ≤ max_lag) at which `b` best matches `a`, and
// the normalised correlation there.
std::pair<int, double> best_lag(const std::vector<float>& a, const std::vector<float>& b, int max_lag) {
    int best = 0;
    double best_r = -2.0;
    for (int lag = -max_lag; lag <= max_lag; ++lag) {
        double ab = 0, aa = 0, bb = 0;
        for (std::size_t i = 0; i < a.size(); ++i) {
            const long j = static_cast<long>(i) + lag;
            if (j < 0 || j >= static_cast<long>(b.size())) continue;
            ab += static_cast<double>(a[i]) * b[static_cast<std::size_t>(j)];
            aa += static_cast<double>(a[i]) * a[i];
            bb += static_cast<double>(b[static_cast<std::size_t>(j)]) * b[static_cast<std::size_t>(j)];
        }
        const double r = aa > 0 && bb > 0 ? ab / std::sqrt(aa * bb) : 0.0;
        if (r > best_r) {
            best_r = r;
            best = lag;
        }
    }
    return {best, best_r};
}

// Real stimuli: `avsi build-stimuli` makes MP4s of 4 short sentences in two
// conditions (audio-only with a still face, and a rule-model face), then a
// scripted session plays them through the null audio device. Every frame of
// every clip must reach the screen once, at its time on the simulated 60 Hz
// audio clock; the audio sent to the device must be the stimulus' audio
// (aligned to the video within 1 ms); the export must hold every response.
TEST_F(RunnerE2E, BuiltStimulusSetPlaysEveryFrameOnTimeWithItsAudio) {
    const fs::path dir = temp_dir("e2e_built");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "built" / "protocol.toml";
    const fs::path stimuli = dir / "stimuli";
    ASSERT_EQ(run_avsi_logged({"build-stimuli", protocol.string(), "--out", stimuli.string(), "--jobs", "2"}, dir / "build.txt"), 0)
        << read_text_file(dir / "build.txt");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli);
    // What the design shows: the 2 test sentences in both conditions, the
    // warm-up sentence in audio-only and the practice sentence in rule.
    ASSERT_EQ(manifest.stimuli.size(), 6u);

    // 4 trials: warm-up, practice (feedback screen), two test blocks; one empty answer.
    // The last answer has letters of other languages (å ä ö ü ß): stored and exported as typed.
    const std::vector<std::string> answers = {"sun warm", "she opened the door", "", "he bought bread: får åtta äpplen, süße"};
    write_text_file(dir / "script.txt", "sun warm\nshe opened the door\n-\nhe bought bread: får åtta äpplen, süße\n");
    const fs::path db = dir / "built.sqlite";
    ASSERT_EQ(run_avsi_logged({"run", protocol.string(), "--subject", "1", "--db", db.string(), "--stimuli", stimuli.string(),
                   "--audio", "null", "--windowed", "--size", "640x480", "--script", (dir / "script.txt").string(),
                   "--screenshots", (dir / "png").string(), "--audio-capture", (dir / "audio").string()},
                  dir / "log.txt"),
              0)
        << read_text_file(dir / "log.txt");
    ASSERT_EQ(run_avsi_logged({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);

    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), answers.size());
    const auto response = responses.require_column("response");
    const auto stimulus = responses.require_column("stimulus");
    std::map<int, std::string> stimulus_of;
    for (std::size_t i = 0; i < answers.size(); ++i) {
        EXPECT_EQ(responses.rows[i].fields[2], std::to_string(i + 1));
        EXPECT_EQ(responses.rows[i].fields[response], answers[i]);
        stimulus_of[static_cast<int>(i + 1)] = responses.rows[i].fields[stimulus];
    }
    std::set<std::string> conditions;
    for (const auto& [trial, path] : stimulus_of) conditions.insert(path.substr(path.find('/') + 1));
    EXPECT_EQ(conditions, (std::set<std::string>{"audio-only.mp4", "rule.mp4"}));

    // Every frame once, at its time on the audio clock (60 Hz simulated, 30 fps clips).
    const CsvTable timing = read_csv(dir / "export" / "timing.csv");
    ASSERT_EQ(timing.rows.size(), answers.size());
    std::map<int, double> onset_of;
    for (const auto& row : timing.rows) {
        const int trial = static_cast<int>(*parse_int(row.fields[timing.require_column("trial")]));
        const ManifestEntry& clip = manifest.stimuli.at(stimulus_of.at(trial));
        SCOPED_TRACE(clip.path);
        EXPECT_EQ(row.fields[timing.require_column("frames_total")], std::to_string(clip.frames));
        EXPECT_EQ(row.fields[timing.require_column("frames_shown")], std::to_string(clip.frames));
        EXPECT_EQ(row.fields[timing.require_column("dropped_frames")], "0");
        EXPECT_EQ(row.fields[timing.require_column("repeated_frames")], "0");
        EXPECT_LE(*parse_double(row.fields[timing.require_column("max_abs_av_offset_ms")]), 1.0);
        onset_of[trial] = *parse_double(row.fields[timing.require_column("audio_onset_s")]);
    }
    const CsvTable frames = read_csv(dir / "export" / "frames.csv");
    std::map<int, std::vector<std::pair<int, double>>> flips;  // trial → (frame, flip_s)
    for (const auto& row : frames.rows)
        flips[static_cast<int>(*parse_int(row.fields[1]))].push_back({static_cast<int>(*parse_int(row.fields[2])),
                                                                      *parse_double(row.fields[4])});
    ASSERT_EQ(flips.size(), answers.size());
    for (const auto& [trial, list] : flips) {
        const ManifestEntry& clip = manifest.stimuli.at(stimulus_of.at(trial));
        SCOPED_TRACE(clip.path);
        ASSERT_EQ(static_cast<int>(list.size()), clip.frames);
        for (int k = 0; k < clip.frames; ++k) {
            EXPECT_EQ(list[static_cast<std::size_t>(k)].first, k);
            // Shown at onset + k/fps (the flip on which it is due), to 1 ms.
            EXPECT_NEAR(list[static_cast<std::size_t>(k)].second - onset_of.at(trial), k / clip.fps, 1e-3) << k;
        }
    }

    // The audio sent to the device is the stimulus' audio (AAC-decoded from
    // the MP4, compared with the builder's WAV), its sample 0 at the first frame.
    for (const auto& [trial, path] : stimulus_of) {
        SCOPED_TRACE(path);
        const Audio sent = read_audio(dir / "audio" / fmt::format("trial{:03}.wav", trial));
        const Audio wav = read_audio(stimuli / (path.substr(0, path.size() - 4) + ".wav"));
        ASSERT_EQ(sent.sample_rate_hz, wav.sample_rate_hz);
        const std::vector<float> original = wav.mono();
        const int ms = sent.sample_rate_hz / 1000;
        // As long as the video (the silence after the speech pads to the last frame).
        const ManifestEntry& clip = manifest.stimuli.at(path);
        EXPECT_NEAR(static_cast<double>(sent.samples.size()) / sent.sample_rate_hz, clip.frames / clip.fps, 0.05);
        const auto [lag, r] = best_lag(original, sent.samples, 20 * ms);
        std::cerr << "[ info ] trial " << trial << " " << path << ": audio lag " << lag << " samples, r = " << r << "\n";
        EXPECT_LE(std::abs(lag), ms) << "audio shifted against the video by " << lag << " samples";
        EXPECT_GT(r, 0.9);
    }

    // Each trial screenshot (taken as frame 0 goes up) shows that clip's
    // decoded frame 0, upright and in place: sampled on a grid of texel
    // centres, the screen matches the frame to a few levels.
    std::set<std::string> kinds;
    int trial_shots = 0;
    for (const auto& entry : fs::directory_iterator(dir / "png")) {
        const std::string name = entry.path().filename().string();
        const std::string kind = name.substr(5, name.rfind("_trial") - 5);
        kinds.insert(kind);
        if (kind != "trial") continue;
        ++trial_shots;
        const int trial = std::stoi(name.substr(name.rfind("_trial") + 6, 3));
        SCOPED_TRACE(name);
        const stimuli::Image shot = stimuli::read_image(entry.path());
        const stimuli::DecodedVideo clip = stimuli::decode_video(stimuli / stimulus_of.at(trial), true);
        const stimuli::Image& frame = clip.frames.front();
        // The runner's layout: scaled to fit 90 % × 80 % of the window, centred.
        const double scale = std::min(shot.width * 0.9 / frame.width, shot.height * 0.8 / frame.height);
        const double x0 = (shot.width - frame.width * scale) / 2, y0 = (shot.height - frame.height * scale) / 2;
        double diff = 0;
        int samples = 0;
        for (int gy = 1; gy < 10; ++gy)
            for (int gx = 1; gx < 10; ++gx) {
                const int fx = frame.width * gx / 10, fy = frame.height * gy / 10;
                const int sx = static_cast<int>(x0 + (fx + 0.5) * scale), sy = static_cast<int>(y0 + (fy + 0.5) * scale);
                for (int c = 0; c < 3; ++c) diff += std::abs(int(frame.pixel(fx, fy)[c]) - int(shot.pixel(sx, sy)[c]));
                samples += 3;
            }
        EXPECT_LE(diff / samples, 6.0);
    }
    EXPECT_EQ(trial_shots, static_cast<int>(answers.size()));
    for (const char* kind : {"instructions", "trial", "response", "confirm-empty", "feedback", "break", "end"})
        EXPECT_TRUE(kinds.count(kind)) << kind;
}

// A real PortAudio stream: ALSA's null plugin as the default device (this
// machine has no sound card). The runner must open it, schedule each onset on
// the stream's DAC timestamps and log the measured A/V offset per trial and
// in the summary. Skipped where PortAudio cannot see the null device.
TEST_F(RunnerE2E, PortAudioStreamSchedulesOnsetsOnTheDacClockAndLogsTheOffset) {
    const fs::path dir = temp_dir("e2e_portaudio");
    const std::string conf = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "asound-null.conf";
    ::setenv("ALSA_CONFIG_PATH", conf.c_str(), 1);
    const int listed = run_avsi_logged({"run", "--list-audio-devices"}, dir / "devices.txt");
    const std::string devices = read_text_file(dir / "devices.txt");
    if (listed != 0 || devices.find("0: default") == std::string::npos) {
        ::unsetenv("ALSA_CONFIG_PATH");
        GTEST_SKIP() << "PortAudio does not list ALSA's null device here:\n" << devices;
    }
    GeneratedStudy g;
    g.conditions = 2;
    g.per_list = 1;
    g.warmup = 0;
    g.practice = 0;
    const fs::path protocol = write_study(dir, g);
    const auto script = write_script(dir / "script.txt", 2, 1);
    const int code = run_avsi_logged({"run", protocol.string(), "--subject", "1", "--db", (dir / "pa.sqlite").string(),
                          "--test-pattern", "--audio", "portaudio", "--audio-device", "default", "--windowed", "--size",
                          "320x240", "--script", script.string()},
                         dir / "log.txt");
    ::unsetenv("ALSA_CONFIG_PATH");
    const std::string log = read_text_file(dir / "log.txt");
    ASSERT_EQ(code, 0) << log;
    EXPECT_NE(log.find("audio: portaudio: default"), std::string::npos) << log;
    for (int trial : {1, 2}) {
        EXPECT_NE(log.find(fmt::format("trial {}: audio onset", trial)), std::string::npos) << log;
        // Real time on a loaded machine may drop frames: the log must state what happened.
        const std::regex line(fmt::format("trial {}: [0-9]+ of 30 frames shown, [0-9]+ dropped, [0-9]+ repeated; A/V "
                                          "offset mean -?[0-9.]+ ms, max \\|offset\\| [0-9.]+ ms",
                                          trial));
        EXPECT_TRUE(std::regex_search(log, line)) << log;
    }
    EXPECT_NE(log.find("timing: 2 presentations"), std::string::npos) << log;
    ASSERT_EQ(run_avsi_logged({"export", (dir / "pa.sqlite").string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable timing = read_csv(dir / "export" / "timing.csv");
    ASSERT_EQ(timing.rows.size(), 2u);
    for (const auto& row : timing.rows) {
        // On the stream clock (seconds since some epoch, not the simulated 0-based clock).
        EXPECT_GT(*parse_double(row.fields[timing.require_column("audio_onset_s")]), 0.0);
        EXPECT_GT(*parse_int(row.fields[timing.require_column("frames_shown")]), 0);
        std::cerr << "[ info ] PortAudio on ALSA null, Xvfb: trial " << row.fields[2] << " dropped "
                  << row.fields[timing.require_column("dropped_frames")] << ", max |A/V offset| "
                  << row.fields[timing.require_column("max_abs_av_offset_ms")] << " ms\n";
    }
}

// A stimulus changed after the build is refused before the session starts.
TEST_F(RunnerE2E, AStimulusChangedAfterTheBuildIsRefused) {
    const fs::path dir = temp_dir("e2e_changed");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "built" / "protocol.toml";
    const fs::path stimuli = dir / "stimuli";
    // Only the first sentence (w01), to keep the test short: the others are reported missing too.
    ASSERT_EQ(run_avsi_logged({"build-stimuli", protocol.string(), "--out", stimuli.string(), "--jobs", "2", "--max-sentences", "1"},
                  dir / "build.txt"),
              0)
        << read_text_file(dir / "build.txt");
    write_text_file(stimuli / "w01" / "audio-only.mp4", read_text_file(stimuli / "w01" / "audio-only.mp4") + "x");
    write_text_file(dir / "script.txt", "a\nb\nc\nd\n");
    EXPECT_EQ(run_avsi_logged({"run", protocol.string(), "--subject", "1", "--db", (dir / "db.sqlite").string(), "--stimuli",
                   stimuli.string(), "--audio", "null", "--windowed", "--script", (dir / "script.txt").string()},
                  dir / "log.txt"),
              1);
    const std::string log = read_text_file(dir / "log.txt");
    EXPECT_NE(log.find("w01/audio-only.mp4: error: sha256: expected"), std::string::npos) << log;
    EXPECT_NE(log.find("changed after the build"), std::string::npos) << log;
    EXPECT_NE(log.find("t02/rule.mp4 is not in the manifest"), std::string::npos) << log;
}

// An adaptive SRT session (tests/data/adaptive: two interleaved HINT-style
// tracks, speech-shaped noise mixed live) killed twice in the middle of its
// tracks and resumed: every presentation's captured device audio is what the
// session mixes for it at the logged level, each track continues
// at the level it left off at, and no trial is lost or answered twice.
TEST_F(RunnerE2E, AdaptiveSessionMixesAtTheLoggedSnrAndResumesMidTrack) {
    const fs::path dir = temp_dir("e2e_adaptive");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "adaptive" / "protocol.toml";
    const Protocol p = load_protocol(protocol);
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const std::vector<PlannedTrial> plan = make_design(p, corpus, 1);
    ASSERT_EQ(plan.size(), 22u);
    // Answers: each track's first sentence wrong once, then right (a repeat);
    // then two of every three test sentences right, the third with nothing.
    std::string script;
    std::set<std::string> started;
    for (std::size_t i = 0; i < plan.size(); ++i) {
        const std::string text = corpus.sentence(plan[i].sentence).text;
        if (plan[i].phase != Phase::Test) script += text + "\n";
        else if (started.insert(plan[i].condition).second) script += "no idea || " + text + "\n";
        else script += i % 3 == 0 ? "-\n" : text + "\n";
    }
    write_text_file(dir / "script.txt", script);
    const fs::path db = dir / "adaptive.sqlite";
    std::vector<std::string> args = run_args(protocol, 1, db, dir / "script.txt");
    args.insert(args.end(), {"--audio-capture", (dir / "audio").string()});
    // Two kills: after the 6th and the 14th committed presentation (both in
    // the tracks), then a run to the end.
    int kills = 0;
    ASSERT_NO_FATAL_FAILURE(kill_at_presentations(args, dir / "log.txt", db, {6, 14}, 26, kills));
    ASSERT_EQ(run_avsi_logged(args, dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    ASSERT_EQ(run_avsi_logged({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);

    // Every planned trial answered once.
    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), plan.size());
    std::set<int> positions;
    for (const auto& row : responses.rows) EXPECT_TRUE(positions.insert(std::stoi(row.fields[2])).second);
    const CsvTable sessions = read_csv(dir / "export" / "sessions.csv");
    EXPECT_EQ(sessions.rows.size(), static_cast<std::size_t>(kills + 1));

    // Every presentation once; each track's levels follow from its own steps
    // across the kills (the next presentation is at the last one's next level),
    // and the protocol's rules replayed on the stored scores give them all.
    const CsvTable t = read_csv(dir / "export" / "adaptive_trials.csv");
    const auto c_trial = t.require_column("trial"), c_attempt = t.require_column("attempt"),
               c_track = t.require_column("track"), c_level = t.require_column("level_db"),
               c_next = t.require_column("next_level_db"), c_keywords = t.require_column("keywords"),
               c_correct = t.require_column("correct"),
               c_presentation = t.require_column("presentation"), c_phase = t.require_column("phase");
    std::set<std::pair<int, int>> seen;
    std::map<std::string, std::vector<const CsvRow*>> tracks;
    int repeats = 0;
    for (const auto& row : t.rows) {
        const int trial = std::stoi(row.fields[c_trial]), attempt = std::stoi(row.fields[c_attempt]);
        EXPECT_TRUE(seen.insert({trial, attempt}).second) << "trial " << trial << " presentation " << attempt << " twice";
        if (attempt > 1) {
            EXPECT_TRUE(seen.count({trial, attempt - 1})) << "trial " << trial << " lost presentation " << attempt - 1;
            ++repeats;
        }
        if (row.fields[c_phase] == "test") tracks[row.fields[c_track]].push_back(&row);
        else EXPECT_EQ(*parse_double(row.fields[c_level]), 10.0);  // the fixed practice SNR
    }
    EXPECT_EQ(repeats, 2);
    ASSERT_EQ(tracks.size(), 2u);
    const analysis::TrackSettings rules = analysis::adaptive_protocol(p).track;
    for (const auto& [name, rows] : tracks) {
        SCOPED_TRACE(name);
        analysis::AdaptiveTrack replay(rules);
        for (std::size_t k = 0; k < rows.size(); ++k) {
            const auto& f = rows[k]->fields;
            EXPECT_EQ(std::stoi(f[c_presentation]), static_cast<int>(k) + 1);
            EXPECT_DOUBLE_EQ(*parse_double(f[c_level]), replay.level_db());
            if (k > 0) {
                EXPECT_DOUBLE_EQ(*parse_double(f[c_level]), *parse_double(rows[k - 1]->fields[c_next]));
            }
            replay.record(std::stoi(f[c_keywords]), std::stoi(f[c_correct]));
            EXPECT_DOUBLE_EQ(*parse_double(f[c_next]), replay.level_db());
        }
        EXPECT_EQ(replay.sentences(), 10);
    }

    // The captured device audio (noise before vocoding, the default): for
    // every presentation, sample for sample what a fresh AdaptiveSession
    // mixes for that trial after the presentations stored before it — the
    // test pattern's audio and the masker vocoded together, the masker
    // running from 0.5 s before the clip to 0.5 s after it.
    // adaptive_session_test.cpp checks that mixture's SNR at the vocoder's
    // input exactly, and the noise-after test below checks it from a capture.
    TestPatternSettings pattern;
    pattern.fps = p.render.fps;
    const auto clip = make_test_pattern(pattern);
    const std::size_t lead = static_cast<std::size_t>(clip->sample_rate() / 2);
    std::vector<Store::AdaptiveRow> stored;
    {
        Store store(db);
        stored = store.adaptive_trials(1);
    }
    ASSERT_EQ(stored.size(), t.rows.size());
    int measured = 0;
    for (std::size_t k = 0; k < stored.size(); ++k) {
        const int trial = stored[k].position, attempt = stored[k].record.attempt;
        const fs::path wav = dir / "audio" / (attempt == 1 ? fmt::format("trial{:03}.wav", trial)
                                                           : fmt::format("trial{:03}_{}.wav", trial, attempt));
        SCOPED_TRACE(wav.string());
        AdaptiveSession replay(p, corpus, std::vector<Store::AdaptiveRow>(stored.begin(), stored.begin() + k),
                               db.string());
        const auto planned =
            std::find_if(plan.begin(), plan.end(), [&](const PlannedTrial& x) { return x.position == trial; });
        ASSERT_NE(planned, plan.end());
        const MixedPresentation m = replay.mix(*planned, clip->audio(), clip->sample_rate());
        EXPECT_EQ(m.level_db, stored[k].record.level_db);
        EXPECT_EQ(m.attempt, attempt);
        const Audio captured = read_audio(wav);
        ASSERT_EQ(captured.samples.size(), lead + clip->audio().size() + lead);
        EXPECT_EQ(captured.samples, m.samples);
        measured += captured.samples == m.samples;
    }
    EXPECT_EQ(measured, static_cast<int>(t.rows.size()));
    std::cerr << "[ info ] " << kills << " kills, " << t.rows.size() << " presentations matched to the session mixture\n";

    // The report on the exported tracks (one subject: no ANOVA, SRTs and plots).
    ASSERT_EQ(run_avsi_logged({"analyze", (dir / "export" / "adaptive_trials.csv").string(), "--protocol", protocol.string(),
                   "--out", (dir / "report").string()},
                  dir / "analyze.txt"),
              0)
        << read_text_file(dir / "analyze.txt");
    const CsvTable srt = read_csv(dir / "report" / "srt.csv");
    ASSERT_EQ(srt.rows.size(), 2u);
    // The methods text names the masker's stage and timing.
    EXPECT_NE(read_text_file(dir / "report" / "report.md").find("added to the speech before vocoding"),
              std::string::npos);
    EXPECT_TRUE(fs::exists(dir / "report" / "tracks" / "subject_1.png"));
}

// noise_stage = "after": the masker is added to the presented (here the
// test pattern's) audio, so the capture is that audio times the logged speech
// gain plus noise at exactly the logged SNR over the clip's span; the masker
// also runs 0.5 s before and after the clip at its level.
TEST_F(RunnerE2E, AdaptiveNoiseAfterVocodingIsAtTheLoggedSnrInTheCapture) {
    const fs::path dir = temp_dir("e2e_adaptive_after");
    const fs::path source = fs::path(AVSI_TEST_DATA_DIR) / "adaptive";
    fs::copy_file(source / "corpus.csv", dir / "corpus.csv");
    const fs::path protocol = dir / "after.toml";
    write_text_file(protocol, read_text_file(source / "protocol.toml") + "noise_stage = \"after\"\n");
    const Protocol p = load_protocol(protocol);
    ASSERT_EQ(analysis::adaptive_protocol(p).noise_stage, analysis::MaskerStage::AfterVocoding);
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const std::vector<PlannedTrial> plan = make_design(p, corpus, 1);
    std::string script;
    for (std::size_t i = 0; i < plan.size(); ++i)
        script += i % 3 == 0 ? std::string("-\n") : corpus.sentence(plan[i].sentence).text + "\n";
    write_text_file(dir / "script.txt", script);
    const fs::path db = dir / "after.sqlite";
    std::vector<std::string> args = run_args(protocol, 1, db, dir / "script.txt");
    args.insert(args.end(), {"--audio-capture", (dir / "audio").string()});
    ASSERT_EQ(run_avsi_logged(args, dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    ASSERT_EQ(run_avsi_logged({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable t = read_csv(dir / "export" / "adaptive_trials.csv");
    const auto c_trial = t.require_column("trial"), c_attempt = t.require_column("attempt"),
               c_level = t.require_column("level_db"), c_gain = t.require_column("speech_gain_db"),
               c_noise = t.require_column("noise_gain_db");
    TestPatternSettings pattern;
    pattern.fps = p.render.fps;
    const auto clip = make_test_pattern(pattern);
    const std::vector<float>& clean = clip->audio();
    const std::size_t lead = static_cast<std::size_t>(clip->sample_rate() / 2);
    int measured = 0;
    for (const auto& row : t.rows) {
        const int trial = std::stoi(row.fields[c_trial]), attempt = std::stoi(row.fields[c_attempt]);
        const fs::path wav = dir / "audio" / (attempt == 1 ? fmt::format("trial{:03}.wav", trial)
                                                           : fmt::format("trial{:03}_{}.wav", trial, attempt));
        SCOPED_TRACE(wav.string());
        const Audio captured = read_audio(wav);
        ASSERT_EQ(captured.samples.size(), lead + clean.size() + lead);
        const double g = std::pow(10.0, *parse_double(row.fields[c_gain]) / 20.0);
        std::vector<double> speech(clean.size());
        double noise_sq = 0;
        for (std::size_t i = 0; i < clean.size(); ++i) {
            speech[i] = g * clean[i];
            const double n = captured.samples[lead + i] - speech[i];
            noise_sq += n * n;
        }
        const double snr = 20 * std::log10(vocoder::speech_level_rms(speech, clip->sample_rate(),
                                                                      vocoder::SnrReference::ActiveFrames) /
                                           std::sqrt(noise_sq / clean.size()));
        EXPECT_NEAR(snr, *parse_double(row.fields[c_level]), 0.01);
        double tail_sq = 0;
        const std::size_t tail_from = lead + clean.size(), tail_to = captured.samples.size() - lead / 10;
        for (std::size_t i = tail_from; i < tail_to; ++i) tail_sq += double(captured.samples[i]) * captured.samples[i];
        // The tail at the noise level: within 3 dB, as the test pattern's line
        // spectrum makes its speech-shaped noise narrowband (slow level swings).
        EXPECT_NEAR(10 * std::log10(tail_sq / double(tail_to - tail_from)), *parse_double(row.fields[c_noise]), 3.0);
        ++measured;
    }
    EXPECT_EQ(measured, static_cast<int>(t.rows.size()));
    EXPECT_GE(measured, 20);
}

// The experimenter's score check: scripted marks after " ## " correct the live
// score; the track steps on the corrected score, the record keeps both and
// the correction is logged. Without experimenter response mode it is refused.
TEST_F(RunnerE2E, AdaptiveScoreCheckCorrectionsCountAndAreLogged) {
    const fs::path dir = temp_dir("e2e_adaptive_check");
    const fs::path source = fs::path(AVSI_TEST_DATA_DIR) / "adaptive";
    fs::copy_file(source / "corpus.csv", dir / "corpus.csv");
    std::string text = read_text_file(source / "protocol.toml");
    text += "confirm_scores = true\n";
    write_text_file(dir / "subject_mode.toml", text);
    text.replace(text.find("[session]\n"), 10, "[session]\nresponse_mode = \"experimenter\"\n");
    write_text_file(dir / "protocol.toml", text);
    const Protocol p = load_protocol(dir / "protocol.toml");
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const std::vector<PlannedTrial> plan = make_design(p, corpus, 1);
    // Every answer typed in full; the experimenter marks the 2nd keyword of
    // every 4th trial after the tracks' first sentences wrong (a correction),
    // and confirms the rest as scored.
    std::string script;
    int corrections = 0;
    for (std::size_t i = 0; i < plan.size(); ++i) {
        script += corpus.sentence(plan[i].sentence).text;
        if (i % 4 == 3 && i > 4) {
            script += " ## 101";
            ++corrections;
        }
        script += "\n";
    }
    write_text_file(dir / "script.txt", script);
    const fs::path db = dir / "check.sqlite";
    EXPECT_EQ(run_avsi_logged(run_args(dir / "subject_mode.toml", 1, db, dir / "script.txt"), dir / "refused.txt"), 1);
    EXPECT_NE(read_text_file(dir / "refused.txt").find("adaptive.confirm_scores: expected session.response_mode"),
              std::string::npos)
        << read_text_file(dir / "refused.txt");
    ASSERT_EQ(run_avsi_logged(run_args(dir / "protocol.toml", 1, db, dir / "script.txt"), dir / "log.txt"), 0)
        << read_text_file(dir / "log.txt");
    Store store(db);
    const auto rows = store.adaptive_trials(1);
    ASSERT_EQ(rows.size(), plan.size());  // all right at first: no repeats
    int corrected = 0;
    for (const auto& row : rows) {
        const bool marked = (row.position - 1) % 4 == 3 && row.position > 5;
        EXPECT_EQ(row.record.auto_correct, 3) << row.position;
        EXPECT_EQ(row.record.corrected, marked) << row.position;
        EXPECT_EQ(row.record.correct, marked ? 2 : 3) << row.position;
        EXPECT_EQ(row.record.marks, marked ? "101" : "111") << row.position;
        corrected += row.record.corrected ? 1 : 0;
    }
    EXPECT_EQ(corrected, corrections);
    int events = 0;
    for (const auto& e : store.events()) events += e.kind == "score-corrected" ? 1 : 0;
    EXPECT_EQ(events, corrections);
    // The tracks stepped on the corrected scores (2 of 3 is not "all right": up).
    for (const auto& row : rows)
        if (row.record.corrected && !row.record.track.empty()) {
            EXPECT_GT(row.record.next_level_db, row.record.level_db);
        }
}

TEST_F(RunnerE2E, ASecondRunnerOnTheSameSubjectRefusesBeforeShowingAnything) {
    const fs::path dir = temp_dir("e2e_two_runners");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "protocol.toml";
    const fs::path db = dir / "two.sqlite";
    const auto script = write_script(dir / "s.txt", 10, 1);
    const pid_t first = start_avsi(run_args(protocol, 1, db, script), dir / "first.txt");
    // Wait until the first runner has committed a trial, then hold it still
    // (between transactions: it holds no SQLite lock) while the second starts.
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (committed(db) < 1 && std::chrono::steady_clock::now() < give_up)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_GE(committed(db), 1) << read_text_file(dir / "first.txt");
    // Stopped outside a write transaction: retried until a write lock is free.
    for (int attempt = 0;; ++attempt) {
        ASSERT_EQ(::kill(first, SIGSTOP), 0);
        sqlite3* h = nullptr;
        bool free = false;
        if (sqlite3_open(db.c_str(), &h) == SQLITE_OK) {
            free = sqlite3_exec(h, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK;
            sqlite3_exec(h, "ROLLBACK", nullptr, nullptr, nullptr);
        }
        sqlite3_close(h);
        if (free) break;
        ASSERT_LT(attempt, 1000);
        ::kill(first, SIGCONT);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::map<std::string, int> before;
    for (const char* t : {"sessions", "responses", "presentations", "events", "runner_locks"}) before[t] = count_rows(db, t);
    auto second_args = run_args(protocol, 1, db, script);
    second_args.push_back("--screenshots");
    second_args.push_back((dir / "shots").string());
    const int second = run_avsi_logged(second_args, dir / "second.txt");
    const std::string second_log = read_text_file(dir / "second.txt");
    for (const auto& [table, n] : before) EXPECT_EQ(count_rows(db, table), n) << table << " changed";
    ::kill(first, SIGCONT);
    int status = 0;
    ::waitpid(first, &status, 0);
    EXPECT_EQ(second, 1) << second_log;
    EXPECT_NE(second_log.find(db.string() + ": error: subject 1 is being run by another runner (process " +
                              std::to_string(first)),
              std::string::npos)
        << second_log;
    // Nothing was shown: no screenshot of any screen.
    EXPECT_FALSE(fs::exists(dir / "shots") && !fs::is_empty(dir / "shots"));
    // The first runner finished undisturbed, and released the lock.
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read_text_file(dir / "first.txt");
    EXPECT_EQ(committed(db), 10);
    EXPECT_EQ(count_rows(db, "runner_locks"), 0u);
}

TEST_F(RunnerE2E, AKillAfterTheLastTrialClosesTheSessionInsteadOfOpeningAnEmptyOne) {
    const fs::path dir = temp_dir("e2e_done");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "protocol.toml";
    const fs::path db = dir / "done.sqlite";
    const auto script = write_script(dir / "s.txt", 10, 1);
    ASSERT_EQ(run_avsi_logged(run_args(protocol, 1, db, script), dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    // As if killed after its last commit: the session never closed, the lock stayed.
    sqlite3* h = nullptr;
    ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(h, "UPDATE sessions SET ended_utc = NULL, end_reason = NULL", nullptr, nullptr, nullptr),
              SQLITE_OK);
    // The dead runner's lock: this host and boot, a process that no longer runs.
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    std::string boot;
    std::getline(std::ifstream("/proc/sys/kernel/random/boot_id"), boot);
    const std::string lock = fmt::format("INSERT INTO runner_locks VALUES(1, 999999, '{}', '{}', 'x', '2026-01-01')",
                                         host, boot);
    ASSERT_EQ(sqlite3_exec(h, lock.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(h);
    const std::size_t sessions = count_rows(db, "sessions");
    EXPECT_EQ(run_avsi_logged(run_args(protocol, 1, db, script), dir / "again.txt"), 1);
    const std::string log = read_text_file(dir / "again.txt");
    EXPECT_NE(log.find("subject 1 has answered all 10 planned trials; nothing to run"), std::string::npos) << log;
    EXPECT_EQ(count_rows(db, "sessions"), sessions) << "a new session was opened";
    Store store(db);
    const auto all = store.sessions(1);
    ASSERT_EQ(all.size(), 1u);
    EXPECT_EQ(all[0].end_reason, "completed");
    EXPECT_EQ(store.answered_positions(1).size(), 10u);
}

// A band-count track (variable = "bands"): the runner plays, for every
// presentation, the stimulus's pre-rendered audio variant at the level it
// logs — the captured device audio is that variant's samples exactly, and no
// other level's — and a session killed twice mid-track resumes at the stored
// next level. The variants here are distinct seeded noises written at the
// planned stimulus paths (the builder's own variants are checked in
// test_stimuli); the video is the test clip.
TEST_F(RunnerE2E, BandCountTrackPlaysTheLoggedVariantAndResumesMidTrack) {
    const fs::path dir = temp_dir("e2e_adaptive_bands");
    const fs::path source = fs::path(AVSI_TEST_DATA_DIR) / "adaptive";
    fs::copy_file(source / "corpus.csv", dir / "corpus.csv");
    std::string text = read_text_file(source / "protocol.toml");
    text = text.substr(0, text.find("[adaptive]"));
    text += "[adaptive]\nprocedure = \"sentence\"\ntracks = \"interleaved\"\nvariable = \"bands\"\n"
            "levels = [1, 2, 4, 8, 16]\nstart_level = 4\nlarge_step_levels = 2\nlarge_steps = 2\n"
            "small_step_levels = 1\nrepeat_first = true\nsrt_from = 5\npractice_level = 16\nreference = \"audio-only\"\n";
    const fs::path protocol = dir / "bands.toml";
    write_text_file(protocol, text);
    const Protocol p = load_protocol(protocol);
    const analysis::AdaptiveProtocol rules = analysis::adaptive_protocol(p);
    ASSERT_TRUE(rules.list_variable());
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const std::vector<PlannedTrial> plan = make_design(p, corpus, 1);
    TestPatternSettings pattern;
    pattern.fps = p.render.fps;
    const auto clip = make_test_pattern(pattern);
    // The variants: seeded noise per stimulus and level, the clip's length and rate.
    const fs::path stimuli = dir / "stimuli";
    std::map<int, std::string> stimulus_of;  // trial position → planned stimulus
    for (const auto& t : plan) {
        stimulus_of[t.position] = t.stimulus;
        for (const double level : rules.levels) {
            const fs::path path = stimuli / stimuli::variant_audio_path(t.stimulus, "bands", level);
            if (fs::exists(path)) continue;
            fs::create_directories(path.parent_path());
            Rng rng(derive_seed(5, path.string()));
            Audio a;
            a.sample_rate_hz = clip->sample_rate();
            a.samples.resize(clip->audio().size());
            for (float& v : a.samples) v = static_cast<float>(0.05 * rng.normal(0.0, 1.0));
            write_audio(path, a);
        }
    }
    std::string script;
    std::set<std::string> started;
    for (std::size_t i = 0; i < plan.size(); ++i) {
        const std::string answer = corpus.sentence(plan[i].sentence).text;
        if (plan[i].phase != Phase::Test) script += answer + "\n";
        else if (started.insert(plan[i].condition).second) script += "no idea || " + answer + "\n";
        else script += i % 3 == 0 ? "-\n" : answer + "\n";
    }
    write_text_file(dir / "script.txt", script);
    const fs::path db = dir / "bands.sqlite";
    std::vector<std::string> args = run_args(protocol, 1, db, dir / "script.txt");
    // Without the stimulus folder the variants cannot be found: refused before the session starts.
    EXPECT_EQ(run_avsi_logged(args, dir / "refused.txt"), 2) << read_text_file(dir / "refused.txt");
    EXPECT_NE(read_text_file(dir / "refused.txt").find("--stimuli"), std::string::npos) << read_text_file(dir / "refused.txt");
    EXPECT_FALSE(fs::exists(db) && count_rows(db, "adaptive_trials") > 0);
    args.insert(args.end(), {"--stimuli", stimuli.string(), "--audio-capture", (dir / "audio").string()});
    int kills = 0;
    ASSERT_NO_FATAL_FAILURE(kill_at_presentations(args, dir / "log.txt", db, {6, 14}, 26, kills));
    ASSERT_EQ(run_avsi_logged(args, dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    ASSERT_EQ(run_avsi_logged({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), plan.size());

    const CsvTable t = read_csv(dir / "export" / "adaptive_trials.csv");
    const auto c_trial = t.require_column("trial"), c_attempt = t.require_column("attempt"),
               c_track = t.require_column("track"), c_level = t.require_column("level_db"),
               c_next = t.require_column("next_level_db"), c_keywords = t.require_column("keywords"),
               c_correct = t.require_column("correct"), c_phase = t.require_column("phase");
    std::set<std::pair<int, int>> seen;
    std::map<std::string, std::vector<const CsvRow*>> tracks;
    int matched = 0;
    for (const auto& row : t.rows) {
        const int trial = std::stoi(row.fields[c_trial]), attempt = std::stoi(row.fields[c_attempt]);
        EXPECT_TRUE(seen.insert({trial, attempt}).second) << "trial " << trial << " presentation " << attempt << " twice";
        const double level = *parse_double(row.fields[c_level]);
        if (row.fields[c_phase] == "test") tracks[row.fields[c_track]].push_back(&row);
        else EXPECT_EQ(level, 16.0);  // the practice level
        // The captured audio is the logged level's variant, sample for sample, and no other level's.
        const fs::path wav = dir / "audio" / (attempt == 1 ? fmt::format("trial{:03}.wav", trial)
                                                           : fmt::format("trial{:03}_{}.wav", trial, attempt));
        SCOPED_TRACE(wav.string());
        const std::vector<float> captured = read_audio(wav).mono();
        for (const double other : rules.levels) {
            const std::vector<float> variant =
                read_audio(stimuli / stimuli::variant_audio_path(stimulus_of.at(trial), "bands", other)).mono();
            if (other == level) {
                EXPECT_EQ(captured, variant);
                matched += captured == variant;
            } else {
                EXPECT_NE(captured, variant);
            }
        }
    }
    EXPECT_EQ(matched, static_cast<int>(t.rows.size()));
    ASSERT_EQ(tracks.size(), 2u);
    for (const auto& [name, rows] : tracks) {
        SCOPED_TRACE(name);
        analysis::AdaptiveTrack replay(rules.track);
        for (std::size_t k = 0; k < rows.size(); ++k) {
            const auto& f = rows[k]->fields;
            EXPECT_DOUBLE_EQ(*parse_double(f[c_level]), rules.value_of(replay.level_db()));
            if (k > 0) {
                EXPECT_DOUBLE_EQ(*parse_double(f[c_level]), *parse_double(rows[k - 1]->fields[c_next]));
            }
            replay.record(std::stoi(f[c_keywords]), std::stoi(f[c_correct]));
            EXPECT_DOUBLE_EQ(*parse_double(f[c_next]), rules.value_of(replay.level_db()));
        }
        EXPECT_EQ(replay.sentences(), 10);
    }
    std::cerr << "[ info ] " << kills << " kills, " << matched << " presentations matched to their variant\n";

    // The threshold on the log2(bands) scale (issue 39), with the bands beside it.
    ASSERT_EQ(run_avsi_logged({"analyze", (dir / "export" / "adaptive_trials.csv").string(), "--protocol", protocol.string(),
                   "--out", (dir / "report").string()},
                  dir / "analyze.txt"),
              0)
        << read_text_file(dir / "analyze.txt");
    const std::string report = read_text_file(dir / "report" / "report.md");
    EXPECT_NE(report.find("SRT by condition (log2 vocoder bands"), std::string::npos) << report;
    EXPECT_NE(report.find("| SRT (bands) |"), std::string::npos) << report;
    EXPECT_NE(read_text_file(dir / "analyze.txt").find("log2(bands)"), std::string::npos) << read_text_file(dir / "analyze.txt");
}

}  // namespace
}  // namespace avsi::experiment
