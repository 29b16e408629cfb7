// `avsi power` and `avsi simulate-srt` as job arrays: the shards merged give
// the unsharded run's result exactly (each replicate keeps its own seed), in
// particular the committed power_sd0.csv of an earlier version, byte for
// byte; the merge refuses a missing, foreign, stale, misnamed or cut-short
// shard, naming it.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "avsi/analysis/adaptive.h"
#include "avsi/analysis/power.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi::analysis {
namespace {

namespace fs = std::filesystem;

void expect_same(const PowerResult& a, const PowerResult& b) {
    ASSERT_EQ(a.points.size(), b.points.size());
    EXPECT_EQ(a.contrast, b.contrast);
    for (std::size_t i = 0; i < a.points.size(); ++i) {
        SCOPED_TRACE(a.points[i].subjects);
        EXPECT_EQ(a.points[i].subjects, b.points[i].subjects);
        EXPECT_EQ(a.points[i].simulations, b.points[i].simulations);
        EXPECT_EQ(a.points[i].power_anova, b.points[i].power_anova);
        EXPECT_EQ(a.points[i].power_anova_gg, b.points[i].power_anova_gg);
        EXPECT_EQ(a.points[i].power_contrast, b.points[i].power_contrast);
        EXPECT_EQ(a.points[i].mc_se_anova, b.points[i].mc_se_anova);
        EXPECT_EQ(a.points[i].mc_se_contrast, b.points[i].mc_se_contrast);
        EXPECT_EQ(a.points[i].mean_percent, b.points[i].mean_percent);
    }
}

std::string error_text(const std::function<void()>& f) {
    try {
        f();
    } catch (const InputError& e) {
        std::string text;
        for (const auto& d : e.diagnostics()) text += d.format() + "\n";
        return text;
    }
    return "";
}

// The settings of tests/data/analysis/power_sd0.csv (power_test.cpp).
PowerSettings sd0_settings() {
    PowerSettings s;
    s.means_percent = {60, 64, 67};
    s.subject_counts = {6, 10, 14};
    s.simulations = 500;
    s.seed = 39;
    s.condition_sd = 0.0;
    return s;
}

// power_sd0.csv was written by the unsharded command before shards existed:
// 4 shards (and 7, which split 500 unevenly) merge into it byte for byte.
TEST(PowerShards, MergedShardsReproduceTheCommittedUnshardedCsv) {
    const PowerSettings s = sd0_settings();
    for (const std::size_t n : {4u, 7u}) {
        SCOPED_TRACE(n);
        const fs::path dir = test::temp_dir("power_shards_" + std::to_string(n));
        for (std::size_t k = 0; k < n; ++k) {
            PowerSettings shard = s;
            shard.threads = 1 + k % 2;  // the thread count is not a setting of the result
            simulate_power_shard(shard, {k, n}, dir);
        }
        write_power_files(dir, merge_power_shards(s, dir));
        EXPECT_EQ(read_text_file(dir / "power.csv"),
                  read_text_file(fs::path(AVSI_TEST_DATA_DIR) / "analysis" / "power_sd0.csv"));
        fs::remove_all(dir);
    }
}

// With the default random slope and more shards than some subject counts
// have experiments for (empty shards), the merge equals the run.
TEST(PowerShards, MergeEqualsTheRunWithEmptyShards) {
    PowerSettings s;
    s.means_percent = {50, 60, 65};
    s.subject_counts = {4, 8};
    s.sentences_per_cell = 4;
    s.simulations = 5;
    s.seed = 8;
    const fs::path dir = test::temp_dir("power_shards_empty");
    for (std::size_t k = 0; k < 8; ++k) simulate_power_shard(s, {k, 8}, dir);
    expect_same(merge_power_shards(s, dir), simulate_power(s));
    fs::remove_all(dir);
}

TEST(PowerShards, MergeRefusesMissingForeignStaleMisnamedAndShortShards) {
    PowerSettings s;
    s.means_percent = {50, 60, 65};
    s.subject_counts = {4, 8};
    s.sentences_per_cell = 4;
    s.simulations = 12;
    s.seed = 8;
    const fs::path dir = test::temp_dir("power_shards_refused");
    for (std::size_t k = 0; k < 3; ++k) simulate_power_shard(s, {k, 3}, dir);
    ASSERT_EQ(error_text([&] { merge_power_shards(s, dir); }), "");
    const fs::path shard1 = dir / "power.shard-1-of-3.csv";
    const std::string good = read_text_file(shard1);

    fs::remove(shard1);
    std::string e = error_text([&] { merge_power_shards(s, dir); });
    EXPECT_EQ(e, shard1.string() + ": error: shard 1/3: missing: shard 1 of 3 was not built (or its task failed); run "
                                   "avsi power … --out DIR --shard 1/3\n");

    PowerSettings other = s;
    other.seed = 9;
    simulate_power_shard(other, {1, 3}, dir);
    e = error_text([&] { merge_power_shards(s, dir); });
    EXPECT_NE(e.find(shard1.string() + ":3: error: settings: foreign: made with other settings: seed 9 (this run: 8)"),
              std::string::npos)
        << e;

    std::string text = good;
    text.replace(text.find("# avsi "), text.find('\n', text.find("# avsi ")) - text.find("# avsi "), "# avsi 0.0.1");
    write_text_file(shard1, text);
    e = error_text([&] { merge_power_shards(s, dir); });
    EXPECT_NE(e.find(shard1.string() + ":2: error: avsi: stale: made by avsi 0.0.1"), std::string::npos) << e;

    // Shard 2's file under shard 1's name: it claims shard 2's experiments.
    fs::copy_file(dir / "power.shard-2-of-3.csv", shard1, fs::copy_options::overwrite_existing);
    e = error_text([&] { merge_power_shards(s, dir); });
    EXPECT_NE(e.find(shard1.string() + ":1: error: shard: claims to be shard 2/3 but is named power.shard-1-of-3.csv"),
              std::string::npos)
        << e;

    // Cut short: the last row of the shard lost (a task killed while writing).
    text = good.substr(0, good.rfind('\n', good.size() - 2) + 1);
    write_text_file(shard1, text);
    e = error_text([&] { merge_power_shards(s, dir); });
    EXPECT_NE(e.find("cut short: shard 1/3 ends before subjects 8 simulation 7"), std::string::npos) << e;

    // A changed value.
    text = good;
    text.replace(text.find("\n4,4,") + 5, 1, "7");
    write_text_file(shard1, text);
    e = error_text([&] { merge_power_shards(s, dir); });
    EXPECT_NE(e.find(shard1.string() + ":5: error: anova: expected 0 or 1, got 7"), std::string::npos) << e;
    fs::remove_all(dir);
}

SrtSimulationSettings srt_settings(AdaptiveProcedure procedure) {
    SrtSimulationSettings s;
    s.track.procedure = procedure;
    s.sentence_counts = {8, 12};
    s.listeners = 23;
    s.seed = 5;
    s.start_offset_sd_db = 2.0;
    s.track.min_reversals = 4;  // some tracks reverse fewer times: unconverged, counted the same way
    return s;
}

// Both procedures, with unconverged tracks left out and kept: the merged
// rows equal the run's, field for field, and so do the CSV files.
TEST(SrtShards, MergeEqualsTheRunNumberForNumber) {
    for (const auto procedure : {AdaptiveProcedure::Sentence, AdaptiveProcedure::Word})
        for (const bool include : {false, true}) {
            SCOPED_TRACE(to_string(procedure) + (include ? " with unconverged" : ""));
            SrtSimulationSettings s = srt_settings(procedure);
            s.include_unconverged = include;
            const fs::path dir = test::temp_dir("srt_shards");
            for (std::size_t k = 0; k < 5; ++k) simulate_srt_shard(s, {k, 5}, dir);
            const SrtSimulationResult merged = merge_srt_shards(s, dir), whole = simulate_srt(s);
            ASSERT_EQ(merged.rows.size(), whole.rows.size());
            int unconverged = 0;
            for (std::size_t i = 0; i < whole.rows.size(); ++i) {
                const auto &a = merged.rows[i], &b = whole.rows[i];
                EXPECT_EQ(a.sentences, b.sentences);
                EXPECT_EQ(a.estimator, b.estimator);
                EXPECT_EQ(a.estimates, b.estimates);
                EXPECT_EQ(a.unconverged, b.unconverged);
                EXPECT_EQ(a.mean_db, b.mean_db);
                EXPECT_EQ(a.sd_db, b.sd_db);
                EXPECT_EQ(a.rmse_db, b.rmse_db);
                EXPECT_EQ(a.mean_presentations, b.mean_presentations);
                unconverged += b.unconverged;
            }
            EXPECT_GT(unconverged, 0);  // min_reversals left some tracks unconverged
            write_srt_simulation(dir / "merged", merged);
            write_srt_simulation(dir / "whole", whole);
            EXPECT_EQ(read_text_file(dir / "merged" / "srt_simulation.csv"),
                      read_text_file(dir / "whole" / "srt_simulation.csv"));
            fs::remove_all(dir);
        }
}

TEST(SrtShards, MergeRefusesAMissingOrForeignShard) {
    const SrtSimulationSettings s = srt_settings(AdaptiveProcedure::Sentence);
    const fs::path dir = test::temp_dir("srt_shards_refused");
    simulate_srt_shard(s, {0, 2}, dir);
    std::string e = error_text([&] { merge_srt_shards(s, dir); });
    EXPECT_NE(e.find("srt_simulation.shard-1-of-2.csv: error: shard 1/2: missing"), std::string::npos) << e;
    SrtSimulationSettings other = s;
    other.listener.l50_db = -4.0;
    simulate_srt_shard(other, {1, 2}, dir);
    e = error_text([&] { merge_srt_shards(s, dir); });
    EXPECT_NE(e.find("foreign: made with other settings: listener {\"ceiling\":1.0,\"keywords\":3,\"l50_db\":-4.0"),
              std::string::npos)
        << e;
    fs::remove_all(dir);
}

// The command line: shards and the merge through `avsi power` give the
// unsharded command's power.csv; a bad --shard is a usage error (exit 2)
// saying what is allowed; --shard without --out too.
TEST(PowerShards, CommandLineShardsMergeIntoTheRunsFiles) {
    const fs::path dir = test::temp_dir("power_shards_cli");
    const std::string options = "power --means 50,60,70 --subjects 6,12 --sentences-per-cell 4 --sims 21 --seed 3";
    ASSERT_EQ(test::run_avsi(options + " --out " + (dir / "whole").string()).exit_code, 0);
    for (const char* k : {"0/3", "1/3", "2/3"}) {
        const test::CliResult r = test::run_avsi(options + " --shard " + k + " --out " + (dir / "split").string());
        ASSERT_EQ(r.exit_code, 0) << r.output();
    }
    const test::CliResult merged = test::run_avsi(options + " --merge --out " + (dir / "split").string());
    ASSERT_EQ(merged.exit_code, 0) << merged.output();
    EXPECT_NE(merged.out.find("Power by simulation"), std::string::npos);
    for (const char* file : {"power.csv", "power.json", "power.txt"})
        EXPECT_EQ(read_text_file(dir / "split" / file), read_text_file(dir / "whole" / file)) << file;

    const test::CliResult last = test::run_avsi(options + " --shard 3/3 --out " + (dir / "split").string());
    EXPECT_EQ(last.exit_code, 2);
    EXPECT_NE(last.err.find("--shard: expected K/N with 0 <= K < N <= 10000 (K counts from 0, as SLURM_ARRAY_TASK_ID "
                            "does): the last of 3 shards is 2/3, got \"3/3\""),
              std::string::npos)
        << last.output();
    const test::CliResult no_out = test::run_avsi(options + " --shard 0/3");
    EXPECT_EQ(no_out.exit_code, 2);
    EXPECT_NE(no_out.err.find("--shard and --merge need --out"), std::string::npos) << no_out.output();
    const test::CliResult both = test::run_avsi(options + " --shard 0/3 --merge --out " + (dir / "split").string());
    EXPECT_EQ(both.exit_code, 2) << both.output();
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi::analysis
