#include "avsi/experiment/store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "test_support.h"

namespace avsi::experiment {
namespace {

using testing::temp_dir;

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

}  // namespace
}  // namespace avsi::experiment
