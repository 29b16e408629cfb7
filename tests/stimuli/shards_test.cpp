// Sharded stimulus builds (stimuli/shards.h): a set built as 4 shards and
// merged has the one-machine build's manifest, QC page and methods text,
// byte for byte, and passes --verify; a re-run shard rebuilds only what is
// missing; the merge refuses a missing, foreign, stale or duplicated shard
// and stimuli that are not in the folder, naming each.
#include <algorithm>
#include <fstream>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/shards.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi::stimuli {
namespace {

const std::filesystem::path data_dir = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "shards";

struct ShardsFixture : ::testing::Test {
    std::filesystem::path dir = test::temp_dir("shards_test");
    void TearDown() override { std::filesystem::remove_all(dir); }
    BuildSettings settings(const std::string& name, ShardSpec shard = {}) const {
        BuildSettings s;
        s.protocol_path = data_dir / "protocol.toml";
        s.out_dir = dir / name;
        s.jobs = 2;
        s.shard = shard;
        return s;
    }
    BuildSettings merge(const std::string& name) const {
        BuildSettings s = settings(name);
        s.merge = true;
        return s;
    }
    // Builds the 4 shards of `name`: shards 0 and 1 in this process, 2 and 3 by the avsi command.
    void build_shards(const std::string& name) const {
        for (std::size_t k = 0; k < 2; ++k) build_stimuli(settings(name, {k, 4}));
        for (const char* k : {"2/4", "3/4"}) {
            const test::CliResult r = test::run_avsi({"build-stimuli", (data_dir / "protocol.toml").string(), "--out",
                                                      (dir / name).string(), "--shard", k, "--jobs", "2"});
            ASSERT_EQ(r.exit_code, 0) << r.output();
        }
    }
    // The merge's error text (every diagnostic), or "" when it succeeds.
    std::string merge_error(const std::string& name) const {
        try {
            build_stimuli(merge(name));
        } catch (const InputError& e) {
            std::string text;
            for (const auto& d : e.diagnostics()) text += d.format() + "\n";
            return text;
        }
        return "";
    }
    nlohmann::json shard_json(const std::string& name, ShardSpec shard) const {
        return nlohmann::json::parse(read_text_file(shard_manifest_path(dir / name, shard)));
    }
    void write_shard_json(const std::string& name, ShardSpec shard, const nlohmann::json& j) const {
        write_text_file(shard_manifest_path(dir / name, shard), j.dump(2) + "\n");
    }
};

// The Must-show: N = 4 shards merged give the one-machine build's manifest
// (every entry, every SHA-256; the manifest has no timing fields, so the
// whole file is the same), QC page and methods text, and --verify passes.
// Two one-machine builds are byte-identical first (else the comparison
// would mean nothing).
TEST_F(ShardsFixture, FourShardsMergeIntoTheOneMachineManifest) {
    const BuildReport one = build_stimuli(settings("one"));
    ASSERT_EQ(one.total, 12u);
    build_stimuli(settings("again"));
    const std::string manifest = read_text_file(dir / "one" / "manifest.json");
    ASSERT_EQ(read_text_file(dir / "again" / "manifest.json"), manifest) << "one-machine builds differ";

    build_shards("sharded");
    // Each shard's manifest lists its own stimuli, which together are the set, each once.
    std::vector<std::string> paths;
    for (std::size_t k = 0; k < 4; ++k) {
        const auto j = shard_json("sharded", {k, 4});
        EXPECT_EQ(j["shard"], k);
        EXPECT_FALSE(j["stimuli"].empty()) << "shard " << k;
        for (const auto& e : j["stimuli"]) paths.push_back(e["path"].get<std::string>());
    }
    std::sort(paths.begin(), paths.end());
    EXPECT_EQ(paths.size(), 12u);
    EXPECT_EQ(std::adjacent_find(paths.begin(), paths.end()), paths.end());
    EXPECT_FALSE(std::filesystem::exists(dir / "sharded" / "manifest.json"));  // shards write no manifest

    const BuildReport merged = build_stimuli(merge("sharded"));
    EXPECT_EQ(merged.total, 12u);
    EXPECT_EQ(merged.rendered, 0u);
    EXPECT_EQ(read_text_file(dir / "sharded" / "manifest.json"), manifest);
    for (const char* file : {"methods.md", "qc/articulation.html"})
        EXPECT_EQ(read_text_file(dir / "sharded" / file), read_text_file(dir / "one" / file)) << file;
    const auto entries = nlohmann::json::parse(manifest)["stimuli"];
    ASSERT_EQ(entries.size(), 12u);
    for (const auto& e : entries)
        EXPECT_EQ(sha256_file(dir / "sharded" / e["path"].get<std::string>()), e["sha256"].get<std::string>());

    const VerifyReport verified = verify_stimuli(settings("sharded"));
    EXPECT_EQ(verified.verified, 12u);
    EXPECT_TRUE(verified.problems.empty()) << verified.problems.front();
}

// The split is by expected frames, not by index: every shard's expected
// frames are within the longest stimulus of the mean, where a split by
// index (3 consecutive stimuli each) puts the two longest sentences' six
// stimuli in two shards.
TEST_F(ShardsFixture, SplitsByExpectedFramesNotByIndex) {
    const ShardPlan plan = plan_shards(settings("x"), 4);
    ASSERT_EQ(plan.stimuli, 12u);
    ASSERT_EQ(plan.expected_frames_per_shard.size(), 4u);
    const double mean = plan.expected_frames / 4.0;
    const double largest = *std::max_element(plan.expected_frames_per_shard.begin(), plan.expected_frames_per_shard.end());
    const double smallest = *std::min_element(plan.expected_frames_per_shard.begin(), plan.expected_frames_per_shard.end());
    // The longest sentence ("longest", 60 letters): 0.5 + 60/14 s at 30 fps.
    const double longest = (0.5 + 60.0 / 14.0) * 30.0;
    EXPECT_LE(largest - mean, longest);
    EXPECT_LE(largest - smallest, longest);
    // By index the last shard would hold the three stimuli of "longest" alone.
    EXPECT_LT(largest, 3.0 * longest);
}

// A re-run shard rebuilds only what is missing (content addressing); a
// forced one rebuilds its own stimuli only.
TEST_F(ShardsFixture, ARerunShardRebuildsOnlyWhatIsMissing) {
    build_stimuli(settings("s", {1, 4}));
    const auto j = shard_json("s", {1, 4});
    ASSERT_GE(j["stimuli"].size(), 2u);
    const std::size_t own = j["stimuli"].size();
    std::filesystem::remove(dir / "s" / j["stimuli"][0]["path"].get<std::string>());
    const BuildReport again = build_stimuli(settings("s", {1, 4}));
    EXPECT_EQ(again.total, own);
    EXPECT_EQ(again.rendered, 1u);
    EXPECT_EQ(again.skipped, own - 1);
    EXPECT_EQ(shard_json("s", {1, 4}), j);  // the same entries, byte for byte in their hashes
    BuildSettings forced = settings("s", {1, 4});
    forced.force = true;
    EXPECT_EQ(build_stimuli(forced).rendered, own);
}

// The refusals, each naming the shard (Must show): a missing shard, a shard
// from another protocol, two shards claiming one stimulus; and a stale
// shard (another avsi), shards of two splits, a stimulus whose MP4 is not in
// the folder (a task that wrote to its node's disk).
TEST_F(ShardsFixture, MergeRefusesMissingForeignStaleAndDuplicatedShards) {
    build_shards("s");
    ASSERT_EQ(merge_error("s"), "");

    // Missing: shard 2 of 4 (its task failed).
    const auto shard2 = shard_manifest_path(dir / "s", {2, 4});
    std::filesystem::rename(shard2, dir / "shard2.json");
    std::string error = merge_error("s");
    EXPECT_NE(error.find("shard-2-of-4.json: error: shard 2/4: missing: shard 2 of 4 was not built"), std::string::npos)
        << error;
    EXPECT_NE(error.find("--shard 2/4"), std::string::npos) << error;
    std::filesystem::rename(dir / "shard2.json", shard2);

    // Foreign: shard 1 rebuilt from another protocol (the same stimuli, one more comment line).
    const std::filesystem::path other = dir / "other";
    std::filesystem::create_directories(other);
    std::string text = read_text_file(data_dir / "protocol.toml");
    const std::string rule = "../../../../protocols/models/rule.json";
    text.replace(text.find(rule), rule.size(),
                 (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").generic_string());
    write_text_file(other / "protocol.toml", "# another study's copy\n" + text);
    std::filesystem::copy_file(data_dir / "corpus.csv", other / "corpus.csv");
    BuildSettings foreign = settings("s", {1, 4});
    foreign.protocol_path = other / "protocol.toml";
    const auto kept = shard_json("s", {1, 4});
    build_stimuli(foreign);
    error = merge_error("s");
    EXPECT_NE(error.find("shard-1-of-4.json: error: shard 1/4: foreign: built from another protocol"), std::string::npos)
        << error;
    write_shard_json("s", {1, 4}, kept);

    // Stale: made by another avsi.
    auto stale = shard_json("s", {3, 4});
    stale["avsi"] = "0.0.1";
    write_shard_json("s", {3, 4}, stale);
    error = merge_error("s");
    EXPECT_NE(error.find("shard-3-of-4.json: error: shard 3/4: stale: built by avsi 0.0.1"), std::string::npos) << error;

    // Duplicated: shard 3 also claims a stimulus of shard 0.
    auto shard3 = stale;
    shard3["avsi"] = shard_json("s", {0, 4})["avsi"];
    const auto first = shard_json("s", {0, 4})["stimuli"][0];
    shard3["stimuli"].push_back(first);
    write_shard_json("s", {3, 4}, shard3);
    error = merge_error("s");
    EXPECT_NE(error.find("shard-3-of-4.json: error: " + first["path"].get<std::string>() +
                         ": duplicated: also claimed by shard-0-of-4.json"),
              std::string::npos)
        << error;
    shard3["stimuli"].erase(shard3["stimuli"].size() - 1);
    write_shard_json("s", {3, 4}, shard3);
    ASSERT_EQ(merge_error("s"), "");

    // A file claiming to be another shard than its name says.
    std::filesystem::copy_file(shard_manifest_path(dir / "s", {0, 4}), dir / "s" / "shards" / "x.json");
    ASSERT_EQ(merge_error("s"), "");  // not a shard file's name: not read
    std::filesystem::remove(dir / "s" / "shards" / "x.json");
    const auto shard0 = shard_manifest_path(dir / "s", {0, 4});
    std::filesystem::rename(shard0, dir / "shard0.json");
    std::filesystem::copy_file(shard_manifest_path(dir / "s", {1, 4}), shard0);
    error = merge_error("s");
    EXPECT_NE(error.find("shard-0-of-4.json: error: shard 0/4: claims to be shard 1/4"), std::string::npos) << error;
    std::filesystem::remove(shard0);
    std::filesystem::rename(dir / "shard0.json", shard0);

    // Shards of two splits in one folder.
    build_stimuli(settings("s", {0, 2}));
    error = merge_error("s");
    EXPECT_NE(error.find("shard files of 2 different splits"), std::string::npos) << error;
    std::filesystem::remove(shard_manifest_path(dir / "s", {0, 2}));

    // A listed MP4 that is not in the folder.
    std::filesystem::remove(dir / "s" / "manifest.json");
    const std::string lost = shard_json("s", {2, 4})["stimuli"][0]["path"].get<std::string>();
    std::filesystem::remove(dir / "s" / lost);
    error = merge_error("s");
    EXPECT_NE(error.find("shard-2-of-4.json: error: " + lost + ": " + lost + " is not in"), std::string::npos) << error;
    EXPECT_FALSE(std::filesystem::exists(dir / "s" / "manifest.json"));
}

// The Slurm scripts of a build: the array of N tasks (K from
// SLURM_ARRAY_TASK_ID), the merge and --verify, the submit script with the
// afterok dependency; all three valid shell (bash -n).
TEST_F(ShardsFixture, WritesTheSlurmArrayTheMergeAndTheSubmitScript) {
    SlurmSettings slurm;
    slurm.shards = 3;
    slurm.time = "00:30:00";
    slurm.mem = "2G";
    slurm.cpus = 2;
    const SlurmScripts s = write_build_slurm_scripts(settings("set"), slurm, dir / "job.sbatch", "/opt/avsi/bin/avsi",
                                                     {"--max-sentences", "3"});
    EXPECT_EQ(s.merge, dir / "job.merge.sbatch");
    EXPECT_EQ(s.submit, dir / "job.submit.sh");
    const std::string array = read_text_file(s.array), merge = read_text_file(s.merge),
                      submit = read_text_file(s.submit);
    for (const std::string& line : std::vector<std::string>{"#SBATCH --array=0-2\n", "#SBATCH --cpus-per-task=2\n", "#SBATCH --mem=2G\n",
                                   "#SBATCH --time=00:30:00\n", "#SBATCH --output=" + (dir / "set" / "slurm").string()})
        EXPECT_NE(array.find(line), std::string::npos) << line << "\n" << array;
    EXPECT_NE(array.find("exec '/opt/avsi/bin/avsi' 'build-stimuli' '" + (data_dir / "protocol.toml").lexically_normal().string() +
                         "' '--out' '" + (dir / "set").string() +
                         "' '--shard' \"${SLURM_ARRAY_TASK_ID}/3\" '--jobs' \"${SLURM_CPUS_PER_TASK:-2}\" "
                         "'--max-sentences' '3'\n"),
              std::string::npos)
        << array;
    EXPECT_EQ(merge.find("--array"), std::string::npos) << merge;
    EXPECT_NE(merge.find("'--merge' '--jobs'"), std::string::npos) << merge;
    EXPECT_NE(merge.find("'--verify' '--jobs'"), std::string::npos) << merge;
    EXPECT_NE(submit.find("--dependency=afterok:\"$array\""), std::string::npos) << submit;
    EXPECT_TRUE(std::filesystem::is_directory(dir / "set" / "slurm"));
    for (const auto& script : {s.array, s.merge, s.submit}) {
        const test::CliResult r = test::run_command("bash -n " + test::shell_quote(script.string()));
        EXPECT_EQ(r.exit_code, 0) << script << ": " << r.output();
    }
    // Run by hand instead of by sbatch, the array script says so.
    const test::CliResult by_hand = test::run_command("env -u SLURM_ARRAY_TASK_ID bash " + test::shell_quote(s.array.string()));
    EXPECT_EQ(by_hand.exit_code, 2);
    EXPECT_NE(by_hand.err.find("submit it with sbatch"), std::string::npos) << by_hand.output();

    slurm.time = "2h";
    slurm.mem = "4GB";
    try {
        write_build_slurm_scripts(settings("set"), slurm, dir / "bad.sbatch", "avsi", {});
        FAIL() << "accepted --time 2h and --mem 4GB";
    } catch (const InputError& e) {
        ASSERT_EQ(e.diagnostics().size(), 2u);
        EXPECT_EQ(e.diagnostics()[0].field, "--time");
        EXPECT_EQ(e.diagnostics()[1].field, "--mem");
    }
}

}  // namespace
}  // namespace avsi::stimuli
