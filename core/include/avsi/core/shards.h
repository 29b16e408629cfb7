// Work split into shards for a cluster (docs/cluster.md): the `--shard K/N`
// option that build-stimuli, simulate-srt and power share, the deterministic
// splits (weighted items by the longest-processing-time rule; replicates in
// contiguous ranges), and the Slurm scripts that run the shards as a job
// array with a merge job that starts once every task has succeeded. Slurm
// does the scheduling, retries and accounting; nothing here schedules.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace avsi {

// The avsi version shard files record (the project's version), so a merge
// refuses shards another avsi made.
std::string avsi_version();

// Shard K of N, K counted from 0 as Slurm's SLURM_ARRAY_TASK_ID is.
struct ShardSpec {
    std::size_t index = 0;  // K, in [0, count)
    std::size_t count = 0;  // N; 0: not sharded
    bool sharded() const { return count > 0; }
    // "K/N", as --shard takes it.
    std::string text() const;
    // "shard-K-of-N", the stem of a shard's files.
    std::string stem() const;
};

// The largest N of --shard K/N and --shards N.
inline constexpr std::size_t max_shards = 10000;

// Parses "K/N" (0 <= K < N <= max_shards). Throws InputError naming
// `option` with what was expected and what was found.
ShardSpec parse_shard(const std::string& text, const std::string& option = "--shard");

// The replicates [first, last) of `shard` among `total`: contiguous, in
// order, the sizes of the N ranges differing by at most one.
std::pair<std::size_t, std::size_t> shard_range(std::size_t total, ShardSpec shard);

// The shard of each item for `shards` shards: items in order of decreasing
// weight (equal weights in index order) each go to the shard with the least
// total weight so far (the lowest index among equals) — Graham's
// longest-processing-time rule, whose largest shard is within 4/3 of the
// best possible split. Deterministic: depends only on the weights.
std::vector<std::size_t> assign_shards(const std::vector<double>& weights, std::size_t shards);

// The same for items whose group shares work (a sentence's stimuli share
// its speech and vocoding, made once per shard): a group weighing at most a
// quarter of a shard's share (total / shards / 4) goes to one shard whole;
// the items of a heavier group go one by one, for balance. Then
// assign_shards over those units, in order of their first item; so no shard
// exceeds the mean by more than a quarter of it or the heaviest item.
std::vector<std::size_t> assign_grouped_shards(const std::vector<double>& weights,
                                               const std::vector<std::size_t>& group_of, std::size_t shards);

// The shard files of one split in a folder, files[K] for shard K of N: the
// files named <prefix>shard-K-of-N<suffix>.
struct ShardFiles {
    std::size_t count = 0;
    std::vector<std::filesystem::path> files;
};

// Finds the shard files in `dir`. Throws InputError naming the folder when
// there are none, when files of two splits (different N) are both there, or
// when a shard is missing: each missing shard named with the command that
// makes it (`rerun` + " --shard K/N").
ShardFiles find_shard_files(const std::filesystem::path& dir, const std::string& prefix, const std::string& suffix,
                            const std::string& rerun);

// The resources each array task (and the merge job) asks Slurm for.
struct SlurmSettings {
    std::size_t shards = 4;
    std::string time = "01:00:00";  // --time, any of Slurm's formats (MM, MM:SS, HH:MM:SS, D-HH[:MM[:SS]])
    std::string mem = "4G";         // --mem, N with an optional unit K, M, G or T
    int cpus = 1;                   // --cpus-per-task
};

// Checks the settings as sbatch would read them; InputError naming the
// option (--shards, --time, --mem, --cpus) for every problem at once.
void validate_slurm_settings(const SlurmSettings& settings);

// What the scripts run. Arguments are written single-quoted, except the
// placeholders "{shard}" (becomes "${SLURM_ARRAY_TASK_ID}/N") and "{cpus}"
// (the task's CPUs, "${SLURM_CPUS_PER_TASK:-<cpus>}").
struct SlurmJob {
    std::string name;                                 // the job name (the merge's gets "-merge")
    std::string what;                                 // a line for the scripts' header comment
    std::filesystem::path log_dir;                    // the tasks' and the merge's logs (created)
    std::vector<std::string> task;                    // one array task: the command and its arguments
    std::vector<std::vector<std::string>> merge;      // the merge job's commands, run in order
};

struct SlurmScripts {
    std::filesystem::path array;   // the job array (the path asked for)
    std::filesystem::path merge;   // <stem>.merge.sbatch beside it
    std::filesystem::path submit;  // <stem>.submit.sh: submits the array, then the merge after it
};

// Writes the array script at `path` (#SBATCH --array=0-(N-1)), the merge
// script and the submit script beside it (`sbatch --parsable` the array,
// then the merge with --dependency=afterok:<array id>; extra sbatch options
// given to the submit script go to both). Throws InputError for bad
// settings, or when a file cannot be written.
SlurmScripts write_slurm_scripts(const std::filesystem::path& path, const SlurmJob& job,
                                 const SlurmSettings& settings);

}  // namespace avsi
