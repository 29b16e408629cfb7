#include "avsi/experiment/store.h"

#include <sched.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <functional>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/sqlite_count.h"
#include "support/temp_dir.h"

namespace avsi::experiment {
namespace {

using test::count_rows;
using test::temp_dir;

std::vector<PlannedTrial> plan_for(int subject, int n) {
    std::vector<PlannedTrial> plan;
    for (int i = 1; i <= n; ++i) {
        PlannedTrial t;
        t.subject = subject;
        t.position = i;
        t.phase = i == 1 ? Phase::Warmup : Phase::Test;
        t.block = i == 1 ? 0 : 1;
        t.list = i == 1 ? "warmup" : "1";
        t.condition = "cm";
        t.sentence = "s" + std::to_string(i);
        t.stimulus = t.sentence + "/cm.mp4";
        plan.push_back(t);
    }
    return plan;
}

TEST(Store, StoresPlansSessionsResponsesAndTiming) {
    const auto db = temp_dir("store") / "e.sqlite";
    {
        Store store(db);
        EXPECT_EQ(store.schema_version(), store_schema_version);
        store.add_subject(3, plan_for(3, 4));
        EXPECT_EQ(store.planned_trials(3), plan_for(3, 4));
        const int session = store.begin_session(3, 1, "test");
        Presentation p;
        p.audio_onset_s = 1.5;
        p.frames_total = 2;
        p.frames_shown = 2;
        p.flips = {{0, 0.0, 1.5, 0.0}, {1, 1.0 / 30, 1.5 + 1.0 / 30, 0.0}};
        store.commit_trial(session, plan_for(3, 4)[0], p, {"hello, \"world\"", 812.5, false});
        store.commit_trial(session, plan_for(3, 4)[2], p, {"", 100.0, true});
        EXPECT_THROW(store.commit_trial(session, plan_for(3, 4)[2], p, {"again", 1.0, false}), std::runtime_error);
        EXPECT_EQ(store.answered_positions(3), (std::vector<int>{1, 3}));
        EXPECT_EQ(store.open_sessions(3).size(), 1u);
    }
    // Reopen: everything committed is still there.
    Store store(db);
    EXPECT_EQ(store.answered_positions(3), (std::vector<int>{1, 3}));
    const auto open = store.open_sessions(3);
    ASSERT_EQ(open.size(), 1u);
    store.mark_interrupted(open[0].session);
    EXPECT_TRUE(store.open_sessions(3).empty());
    EXPECT_EQ(store.sessions(3)[0].end_reason, "interrupted");
    const auto timing = store.timing(true);
    ASSERT_EQ(timing.size(), 2u);
    EXPECT_EQ(timing[0].presentation.flips.size(), 2u);
    EXPECT_DOUBLE_EQ(timing[0].presentation.audio_onset_s, 1.5);

    const auto out = db.parent_path() / "export";
    export_store(store, out);
    const CsvTable responses = read_csv(out / "responses.csv");
    const std::vector<std::string> analysis_columns = {"subject", "session", "trial",    "phase",
                                                       "condition", "list", "sentence", "response"};
    ASSERT_GE(responses.header.size(), analysis_columns.size());
    EXPECT_EQ(std::vector<std::string>(responses.header.begin(), responses.header.begin() + 8), analysis_columns);
    ASSERT_EQ(responses.rows.size(), 2u);
    EXPECT_EQ(responses.rows[0].fields[7], "hello, \"world\"");
    EXPECT_EQ(responses.rows[1].fields[2], "3");
    EXPECT_EQ(read_csv(out / "frames.csv").rows.size(), 4u);
    const CsvTable summary = read_csv(out / "timing_summary.csv");
    ASSERT_EQ(summary.rows.size(), 1u);
    EXPECT_EQ(summary.rows[0].fields[2], "2");  // presentations
    EXPECT_EQ(summary.rows[0].fields[3], "4");  // frames
    EXPECT_EQ(read_csv(out / "sessions.csv").rows.at(0).fields.at(4), "interrupted");
}

TEST(Store, RefusesANewerSchemaAndForeignDatabases) {
    const auto dir = temp_dir("store_versions");
    { Store store(dir / "new.sqlite"); }
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir / "new.sqlite").c_str(), &db), SQLITE_OK);
    sqlite3_exec(db, "PRAGMA user_version=99", nullptr, nullptr, nullptr);
    sqlite3_close(db);
    try {
        Store store(dir / "new.sqlite");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(fmt::format("schema version 99, newer than this avsi supports ({})", store_schema_version)), std::string::npos);
    }
    ASSERT_EQ(sqlite3_open((dir / "other.sqlite").c_str(), &db), SQLITE_OK);
    sqlite3_exec(db, "CREATE TABLE t(x)", nullptr, nullptr, nullptr);
    sqlite3_close(db);
    EXPECT_THROW(Store(dir / "other.sqlite"), InputError);
}

TEST(Store, UsesWalAndFullSync) {
    const auto path = temp_dir("store_pragmas") / "p.sqlite";
    Store store(path);
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    sqlite3_prepare_v2(db, "PRAGMA journal_mode", -1, &st, nullptr);
    ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
    EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)), "wal");
    sqlite3_finalize(st);
    sqlite3_close(db);
}

// Runs `body` in a forked child and returns its exit status (the child exits
// with body's result; 77 means "cannot run here", a skip).
int in_child(const std::function<int()>& body) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        int code = 1;
        try {
            code = body();
        } catch (const std::exception& e) {
            std::fprintf(stderr, "child: unexpected exception: %s\n", e.what());
        }
        std::fflush(stderr);
        ::_exit(code);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// In the calling (child) process: a private mount namespace with a tmpfs of
// `size` at `dir` (root only; false where not permitted).
bool private_tmpfs(const std::filesystem::path& dir, const std::string& options) {
    std::filesystem::create_directories(dir);
    if (::unshare(CLONE_NEWNS) != 0) return false;
    if (::mount("none", "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) return false;
    return ::mount("tmpfs", dir.c_str(), "tmpfs", 0, options.c_str()) == 0;
}

TEST(StoreLock, ASecondProcessIsRefusedWhileTheFirstHoldsTheSubject) {
    const auto db = temp_dir("store_lock") / "l.sqlite";
    Store store(db);
    store.add_subject(1, plan_for(1, 3));
    EXPECT_EQ(store.lock_subject(1), "");
    EXPECT_EQ(store.lock_subject(1), "");  // taking it again in the same process is fine
    const pid_t holder = ::getpid();
    const int refused = in_child([&] {
        Store other(db);
        try {
            other.lock_subject(1);
            return 1;
        } catch (const InputError& e) {
            const std::string what = e.what();
            std::fprintf(stderr, "%s\n", what.c_str());
            const bool ok = what.find(db.string()) != std::string::npos &&
                            what.find("subject 1 is being run by another runner (process " +
                                      std::to_string(holder)) != std::string::npos;
            // Another subject is free.
            other.lock_subject(2);
            return ok ? 0 : 2;
        }
    });
    EXPECT_EQ(refused, 0);
    store.unlock_subject(1);
    EXPECT_EQ(in_child([&] { return Store(db).lock_subject(1).empty() ? 0 : 1; }), 0);
}

TEST(StoreLock, ALockLeftByAKilledProcessIsBrokenByTheNext) {
    const auto db = temp_dir("store_lock_stale") / "l.sqlite";
    { Store store(db); }
    // The child takes the lock and dies without releasing it (_exit skips
    // every destructor, as a kill would).
    ASSERT_EQ(in_child([&] {
                  auto* leaked = new Store(db);
                  leaked->lock_subject(4);
                  ::_exit(0);
                  return 0;
              }),
              0);
    EXPECT_EQ(count_rows(db, "runner_locks"), 1);
    Store store(db);
    const std::string broken = store.lock_subject(4);
    EXPECT_NE(broken.find("no longer running) was broken"), std::string::npos) << broken;
    EXPECT_EQ(count_rows(db, "runner_locks"), 1);
}

TEST(StoreLock, TheLockIsReleasedWhenTheStoreCloses) {
    const auto db = temp_dir("store_lock_release") / "l.sqlite";
    {
        Store store(db);
        store.lock_subject(7);
        EXPECT_EQ(count_rows(db, "runner_locks"), 1);
    }
    EXPECT_EQ(count_rows(db, "runner_locks"), 0);
}

TEST(StoreFailures, AReadOnlyLocationIsNamedWhenOpening) {
    const auto dir = temp_dir("store_readonly");
    { Store store(dir / "ro" / "r.sqlite"); }
    const int code = in_child([&] {
        const auto ro = dir / "ro";
        if (::geteuid() == 0) {
            // Root writes through permissions: a read-only bind mount instead.
            if (::unshare(CLONE_NEWNS) != 0 || ::mount("none", "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0 ||
                ::mount(ro.c_str(), ro.c_str(), nullptr, MS_BIND, nullptr) != 0 ||
                ::mount(nullptr, ro.c_str(), nullptr, MS_BIND | MS_REMOUNT | MS_RDONLY, nullptr) != 0)
                return 77;
        } else {
            std::filesystem::permissions(ro, std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
            std::filesystem::permissions(ro / "r.sqlite", std::filesystem::perms::owner_read);
        }
        try {
            Store store(ro / "r.sqlite");
            return 1;
        } catch (const InputError& e) {
            const std::string what = e.what();
            std::fprintf(stderr, "%s\n", what.c_str());
            return what.find((ro / "r.sqlite").string()) != std::string::npos &&
                           what.find("read-only") != std::string::npos
                       ? 0
                       : 2;
        }
    });
    std::filesystem::permissions(dir / "ro", std::filesystem::perms::owner_all);
    if (code == 77) GTEST_SKIP() << "cannot make a read-only mount here";
    EXPECT_EQ(code, 0);
}

TEST(StoreFailures, AFullDiskNamesTheDatabaseAndKeepsWhatWasCommitted) {
    const auto dir = temp_dir("store_full") / "disk";
    const int code = in_child([&] {
        if (!private_tmpfs(dir, "size=512k")) return 77;
        const auto db = dir / "full.sqlite";
        // A filler to free once the disk is full, so the check below can
        // read (SQLite's shared-memory file needs room too).
        write_text_file(dir / "filler", std::string(64 * 1024, 'f'));
        int committed = 0;
        try {
            Store store(db);
            const auto plan = plan_for(1, 200);
            store.add_subject(1, plan);
            const int session = store.begin_session(1, 1, "disk full test");
            Presentation p;
            p.frames_total = 60;
            for (int f = 0; f < 60; ++f) p.flips.push_back({f, f / 60.0, f / 60.0, 0.0});
            for (const auto& t : plan) {
                store.commit_trial(session, t, p, {std::string(500, 'x'), 100.0, false});
                ++committed;
            }
            std::fprintf(stderr, "never full\n");
            return 1;
        } catch (const InputError& e) {
            const std::string what = e.what();
            std::fprintf(stderr, "after %d trials: %s\n", committed, what.c_str());
            if (what.find(db.string()) == std::string::npos || what.find("disk full") == std::string::npos) return 2;
        }
        // Everything committed before the disk filled is there.
        if (committed < 1) return 3;
        std::filesystem::remove(dir / "filler");
        const int kept = count_rows(db, "responses");
        std::fprintf(stderr, "kept %d of %d\n", kept, committed);
        return kept == committed ? 0 : 4;
    });
    if (code == 77) GTEST_SKIP() << "cannot mount a small tmpfs here (needs root)";
    EXPECT_EQ(code, 0);
}

}  // namespace
}  // namespace avsi::experiment
