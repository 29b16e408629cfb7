// End-to-end runs of `avsi run` / `avsi export` under a private Xvfb server
// with the null audio device (simulated clock): scripted sessions, SIGKILL
// crash safety with resume, and screenshots.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <chrono>
#include <map>
#include <set>
#include <thread>
#include <algorithm>
#include <cmath>

#include "avsi/core/csv.h"
#include "avsi/core/rng.h"
#include "avsi/experiment/store.h"
#include "test_support.h"

namespace avsi::experiment {
namespace {

using testing::GeneratedStudy;
using testing::temp_dir;
using testing::write_study;
namespace fs = std::filesystem;

// One Xvfb server for the whole suite; DISPLAY points at it.
class RunnerE2E : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (::access("/usr/bin/Xvfb", X_OK) != 0) return;
        int fds[2];
        ASSERT_EQ(::pipe(fds), 0);
        s_xvfb = ::fork();
        if (s_xvfb == 0) {
            ::close(fds[0]);
            const int null = ::open("/dev/null", O_WRONLY);
            ::dup2(null, 1);
            ::dup2(null, 2);
            const std::string fd = std::to_string(fds[1]);
            ::execl("/usr/bin/Xvfb", "Xvfb", "-displayfd", fd.c_str(), "-screen", "0", "1024x768x24", "-nolisten",
                    "tcp", static_cast<char*>(nullptr));
            ::_exit(127);
        }
        ::close(fds[1]);
        std::string number;
        char c = 0;
        while (::read(fds[0], &c, 1) == 1 && c != '\n') number += c;
        ::close(fds[0]);
        if (!number.empty()) ::setenv("DISPLAY", (":" + number).c_str(), 1);
        else s_xvfb = -1;
    }
    static void TearDownTestSuite() {
        if (s_xvfb > 0) {
            ::kill(s_xvfb, SIGTERM);
            ::waitpid(s_xvfb, nullptr, 0);
        }
    }
    void SetUp() override {
        if (s_xvfb <= 0) GTEST_SKIP() << "Xvfb is not available";
    }

    // Starts `avsi` with arguments, output to `log`; returns its pid.
    static pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
        const pid_t pid = ::fork();
        if (pid == 0) {
            const int out = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
            ::dup2(out, 1);
            ::dup2(out, 2);
            std::vector<char*> argv;
            argv.push_back(const_cast<char*>(AVSI_CLI_PATH));
            for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
            argv.push_back(nullptr);
            ::execv(AVSI_CLI_PATH, argv.data());
            ::_exit(127);
        }
        return pid;
    }
    static int run(const std::vector<std::string>& args, const fs::path& log) {
        int status = 0;
        ::waitpid(spawn(args, log), &status, 0);
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
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

    // Responses committed so far, read without writing (0 before the database exists).
    static int committed(const fs::path& db) {
        if (!fs::exists(db)) return 0;
        sqlite3* handle = nullptr;
        int n = 0;
        if (sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
            sqlite3_busy_timeout(handle, 2000);
            sqlite3_stmt* st = nullptr;
            if (sqlite3_prepare_v2(handle, "SELECT count(*) FROM responses", -1, &st, nullptr) == SQLITE_OK &&
                sqlite3_step(st) == SQLITE_ROW)
                n = sqlite3_column_int(st, 0);
            sqlite3_finalize(st);
        }
        sqlite3_close(handle);
        return n;
    }

    static inline pid_t s_xvfb = -1;
};

TEST_F(RunnerE2E, ScriptedSessionsForTwoSubjectsCompleteAndExportEveryResponse) {
    const fs::path dir = temp_dir("e2e_two");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "protocol.toml";
    const fs::path db = dir / "exp.sqlite";
    for (int subject : {1, 2}) {
        const auto script = write_script(dir / fmt::format("s{}.txt", subject), 10, subject);
        ASSERT_EQ(run(run_args(protocol, subject, db, script), dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    }
    ASSERT_EQ(run({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), 20u);
    for (std::size_t i = 0; i < responses.rows.size(); ++i) {
        const auto& f = responses.rows[i].fields;
        const int subject = static_cast<int>(i / 10) + 1, trial = static_cast<int>(i % 10) + 1;
        EXPECT_EQ(f[0], std::to_string(subject));
        EXPECT_EQ(f[2], std::to_string(trial));
        EXPECT_EQ(f[7], trial % 5 == 0 ? "" : fmt::format("answer {} {}", subject, trial));
    }
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
    Rng rng(20260);
    SCOPED_TRACE("seed 20260");
    std::vector<PlannedTrial> first_plan;
    std::vector<int> answered_before;
    int kills = 0;
    bool done = false;
    for (int attempt = 0; attempt < 80 && !done; ++attempt) {
        // Kill at a random point: after 0–2 more committed responses, then
        // 0–300 ms into the next trial (fixation, stimulus or answer box).
        const int target = static_cast<int>(answered_before.size() + rng.uniform_int(3));
        const auto extra = std::chrono::milliseconds(rng.uniform_int(300));
        const pid_t pid = spawn(args, dir / "log.txt");
        int status = 0;
        pid_t finished = 0;
        auto deadline = std::chrono::steady_clock::time_point::max();
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
        while ((finished = ::waitpid(pid, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline &&
               std::chrono::steady_clock::now() < give_up) {
            if (deadline == std::chrono::steady_clock::time_point::max() && committed(db) >= target)
                deadline = std::chrono::steady_clock::now() + extra;
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        if (finished == pid) {
            ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << read_text_file(dir / "log.txt");
            done = true;
        } else {
            ::kill(pid, SIGKILL);
            ::waitpid(pid, &status, 0);
            ++kills;
        }
        if (!fs::exists(db)) continue;
        Store store(db);
        const auto plan = store.planned_trials(1);
        if (first_plan.empty()) first_plan = plan;
        if (!plan.empty()) {
            EXPECT_EQ(plan, first_plan) << "the trial sequence changed after a kill";
        }
        const auto answered = store.answered_positions(1);
        // Nothing committed is lost: the answered set only grows.
        EXPECT_TRUE(std::includes(answered.begin(), answered.end(), answered_before.begin(), answered_before.end()));
        answered_before = answered;
    }
    ASSERT_TRUE(done) << "the session never completed";
    EXPECT_GE(kills, 5);
    EXPECT_GE(trials, 20);
    ASSERT_EQ(run({"export", db.string(), "--out", (dir / "export").string()}, dir / "log.txt"), 0);
    const CsvTable responses = read_csv(dir / "export" / "responses.csv");
    ASSERT_EQ(responses.rows.size(), static_cast<std::size_t>(trials));
    std::set<int> positions;
    for (const auto& row : responses.rows) {
        const int trial = static_cast<int>(*parse_int(row.fields[2]));
        EXPECT_TRUE(positions.insert(trial).second) << "trial " << trial << " answered twice";
        EXPECT_EQ(row.fields[7], trial % 5 == 0 ? "" : fmt::format("answer 1 {}", trial));
    }
    ASSERT_EQ(first_plan.size(), static_cast<std::size_t>(trials));
    // Each kill left an open session that the next run recorded as interrupted.
    const CsvTable sessions = read_csv(dir / "export" / "sessions.csv");
    int interrupted = 0;
    for (const auto& row : sessions.rows) interrupted += row.fields[4] == "interrupted";
    EXPECT_GE(interrupted, 1);
    EXPECT_EQ(sessions.rows.back().fields[4], "completed");
    std::cerr << "[ info ] " << kills << " kills, " << sessions.rows.size() << " sessions, " << interrupted
              << " recorded as interrupted\n";
}

TEST_F(RunnerE2E, ScreenshotsOfEveryScreenKind) {
    const fs::path dir = temp_dir("e2e_shots");
    const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "experiment" / "protocol.toml";
    const auto script = write_script(dir / "s.txt", 10, 1);
    auto args = run_args(protocol, 1, dir / "shots.sqlite", script);
    args.push_back("--screenshots");
    args.push_back((dir / "png").string());
    ASSERT_EQ(run(args, dir / "log.txt"), 0) << read_text_file(dir / "log.txt");
    std::set<std::string> kinds;
    for (const auto& entry : fs::directory_iterator(dir / "png")) {
        const std::string name = entry.path().filename().string();
        kinds.insert(name.substr(5, name.rfind("_trial") - 5));
        EXPECT_GT(fs::file_size(entry.path()), 200u);
    }
    for (const char* kind : {"instructions", "fixation", "trial", "response", "confirm-empty", "feedback", "break", "end"})
        EXPECT_TRUE(kinds.count(kind)) << kind;
}

}  // namespace
}  // namespace avsi::experiment
