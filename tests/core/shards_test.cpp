// Shards (core/shards.h): --shard K/N parsed with the allowed range in the
// error, replicate ranges that tile the replicates, the longest-first split
// against a hand-worked example and its bound, and the shard files of a
// folder found, with a missing shard and two splits named.
#include <algorithm>
#include <numeric>

#include <gtest/gtest.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/shards.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

std::string message(const std::string& text) {
    try {
        parse_shard(text);
    } catch (const InputError& e) {
        return e.first().field + ": " + e.first().message;
    }
    return "";
}

TEST(Shards, ParsesKOfNCountingFromZero) {
    const ShardSpec s = parse_shard("3/4");
    EXPECT_EQ(s.index, 3u);
    EXPECT_EQ(s.count, 4u);
    EXPECT_EQ(s.text(), "3/4");
    EXPECT_EQ(s.stem(), "shard-3-of-4");
    EXPECT_TRUE(s.sharded());
    EXPECT_FALSE(ShardSpec{}.sharded());
    EXPECT_EQ(parse_shard("0/1").count, 1u);
    EXPECT_EQ(message("4/4"), "--shard: expected K/N with 0 <= K < N <= 10000 (K counts from 0, as "
                              "SLURM_ARRAY_TASK_ID does): the last of 4 shards is 3/4, got \"4/4\"");
    for (const char* bad : {"", "2", "1/0", "-1/4", "a/b", "1/4/2", "1/10001", "1.5/4", " /4"}) {
        SCOPED_TRACE(bad);
        EXPECT_NE(message(bad).find("expected K/N"), std::string::npos) << message(bad);
    }
}

// floor(K·total/N): sizes differ by at most one, ranges tile [0, total).
TEST(Shards, RangesTileTheReplicates) {
    EXPECT_EQ(shard_range(10, {0, 4}), (std::pair<std::size_t, std::size_t>{0, 2}));
    EXPECT_EQ(shard_range(10, {1, 4}), (std::pair<std::size_t, std::size_t>{2, 5}));
    EXPECT_EQ(shard_range(10, {2, 4}), (std::pair<std::size_t, std::size_t>{5, 7}));
    EXPECT_EQ(shard_range(10, {3, 4}), (std::pair<std::size_t, std::size_t>{7, 10}));
    EXPECT_EQ(shard_range(3, {0, 4}), (std::pair<std::size_t, std::size_t>{0, 0}));
    EXPECT_EQ(shard_range(7, {}), (std::pair<std::size_t, std::size_t>{0, 7}));
    for (std::size_t total : {0u, 1u, 5u, 999u, 1000000u})
        for (std::size_t n : {1u, 2u, 3u, 7u, 100u}) {
            SCOPED_TRACE(std::to_string(total) + " over " + std::to_string(n));
            std::size_t next = 0;
            for (std::size_t k = 0; k < n; ++k) {
                const auto [first, last] = shard_range(total, {k, n});
                EXPECT_EQ(first, next);
                EXPECT_LE(last - first, total / n + 1);
                EXPECT_GE(last - first, total / n);
                next = last;
            }
            EXPECT_EQ(next, total);
        }
}

// Worked by hand: 5→0, 4→1, 3→1 (loads 5, 7), 3→0 (8, 7), 2→1 (8, 9),
// 2→0 (10, 9), 1→1 (10, 10).
TEST(Shards, SplitsTheLongestFirstToTheLeastLoaded) {
    EXPECT_EQ(assign_shards({5, 4, 3, 3, 2, 2, 1}, 2), (std::vector<std::size_t>{0, 1, 1, 0, 1, 0, 1}));
    // Order of the items does not matter to the loads, only to which index goes where.
    EXPECT_EQ(assign_shards({1, 2, 3, 4}, 4), (std::vector<std::size_t>{3, 2, 1, 0}));
    EXPECT_EQ(assign_shards({}, 3), std::vector<std::size_t>{});
    // A sweep: every shard within one item of the mean (the list-scheduling bound).
    std::vector<double> weights;
    for (int i = 0; i < 500; ++i) weights.push_back(30.0 + (i * 7919) % 211);
    for (std::size_t n : {2u, 5u, 16u, 64u}) {
        const auto shard_of = assign_shards(weights, n);
        std::vector<double> load(n, 0.0);
        for (std::size_t i = 0; i < weights.size(); ++i) load[shard_of[i]] += weights[i];
        const double mean = std::accumulate(load.begin(), load.end(), 0.0) / double(n);
        const double heaviest = *std::max_element(weights.begin(), weights.end());
        EXPECT_LE(*std::max_element(load.begin(), load.end()) - mean, heaviest) << n;
        EXPECT_EQ(assign_shards(weights, n), shard_of);  // deterministic
    }
}

// Worked by hand: total 16 over 2 shards, a quarter of a share is 2. The
// group of the two 4s (8) is split; the pairs of 1s (2 each) stay whole:
// units 4, 4, 2, 2, 2, 2 → shards 0, 1, 0, 1, 0, 1.
TEST(Shards, KeepsLightGroupsTogetherAndSplitsHeavyOnes) {
    EXPECT_EQ(assign_grouped_shards({4, 4, 1, 1, 1, 1, 1, 1, 1, 1}, {0, 0, 1, 1, 2, 2, 3, 3, 4, 4}, 2),
              (std::vector<std::size_t>{0, 1, 0, 0, 1, 1, 0, 0, 1, 1}));
    // Many light groups (sentences of 6 stimuli over 8 shards): each group in
    // one shard, every shard within a quarter of the mean.
    std::vector<double> weights;
    std::vector<std::size_t> groups;
    for (std::size_t g = 0; g < 200; ++g)
        for (int c = 0; c < 6; ++c) {
            weights.push_back(40.0 + double((g * 37) % 90));
            groups.push_back(g);
        }
    const auto shard_of = assign_grouped_shards(weights, groups, 8);
    std::vector<double> load(8, 0.0);
    for (std::size_t i = 0; i < weights.size(); ++i) {
        load[shard_of[i]] += weights[i];
        EXPECT_EQ(shard_of[i], shard_of[i - i % 6]) << "group " << groups[i] << " split";
    }
    const double mean = std::accumulate(load.begin(), load.end(), 0.0) / 8.0;
    EXPECT_LE(*std::max_element(load.begin(), load.end()), 1.25 * mean);
}

TEST(Shards, FindsTheShardFilesAndNamesAMissingOne) {
    const auto dir = test::temp_dir("shard_files");
    const auto error = [&] {
        try {
            find_shard_files(dir, "power.", ".csv", "avsi power … --out DIR");
        } catch (const InputError& e) {
            std::string text;
            for (const auto& d : e.diagnostics()) text += d.format() + "\n";
            return text;
        }
        return std::string();
    };
    EXPECT_NE(error().find("no shard files"), std::string::npos);
    for (const char* name : {"power.shard-0-of-3.csv", "power.shard-2-of-3.csv", "power.csv", "other.shard-1-of-3.csv"})
        write_text_file(dir / name, "x");
    EXPECT_EQ(error(), (dir / "power.shard-1-of-3.csv").string() +
                           ": error: shard 1/3: missing: shard 1 of 3 was not built (or its task failed); run avsi "
                           "power … --out DIR --shard 1/3\n");
    write_text_file(dir / "power.shard-1-of-3.csv", "x");
    const ShardFiles found = find_shard_files(dir, "power.", ".csv", "avsi power");
    EXPECT_EQ(found.count, 3u);
    ASSERT_EQ(found.files.size(), 3u);
    EXPECT_EQ(found.files[1], dir / "power.shard-1-of-3.csv");
    write_text_file(dir / "power.shard-0-of-2.csv", "x");
    EXPECT_NE(error().find("shard files of 2 different splits: 1 of 2 (power.shard-0-of-2.csv…); 3 of 3"),
              std::string::npos)
        << error();
    std::filesystem::remove_all(dir);
}

TEST(Shards, RefusesSlurmSettingsSbatchWouldNotRead) {
    SlurmSettings s;
    EXPECT_NO_THROW(validate_slurm_settings(s));
    for (const char* time : {"30", "30:00", "02:00:00", "1-12", "1-12:30", "1-12:30:00"}) {
        s.time = time;
        EXPECT_NO_THROW(validate_slurm_settings(s)) << time;
    }
    for (const char* mem : {"4000", "512M", "4G", "1T"}) {
        s.mem = mem;
        EXPECT_NO_THROW(validate_slurm_settings(s)) << mem;
    }
    s.time = "2h";
    s.mem = "4 GB";
    s.cpus = 0;
    s.shards = 0;
    try {
        validate_slurm_settings(s);
        FAIL();
    } catch (const InputError& e) {
        std::vector<std::string> fields;
        for (const auto& d : e.diagnostics()) fields.push_back(d.field);
        EXPECT_EQ(fields, (std::vector<std::string>{"--shards", "--time", "--mem", "--cpus"}));
    }
}

}  // namespace
}  // namespace avsi
