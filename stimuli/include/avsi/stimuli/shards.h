// A stimulus set built on a cluster (docs/cluster.md).
//
// `build-stimuli P --out DIR --shard K/N` (BuildSettings::shard) builds shard
// K of N: the protocol's stimuli are split by their expected frame count
// (each sentence's expected duration × fps; the longest first to the least
// loaded shard, shards.h in core; a sentence's stimuli together, sharing
// its speech, unless they weigh more than a quarter of a shard's share),
// the same split on every node. It writes the shard's stimuli into DIR as
// a one-machine build does and
// DIR/shards/shard-K-of-N.json: the protocol's SHA-256, the SHA-256 of every
// stimulus's inputs, the builder and avsi versions, and the shard's manifest
// entries. A re-run rebuilds only what is missing or out of date (the input
// hash and file SHA-256 of its earlier shard manifest or of DIR/manifest.json).
//
// `--merge` (BuildSettings::merge) builds nothing: it checks that every shard
// of the split is there, made from this protocol with the same inputs by the
// same avsi, that every stimulus is in exactly one shard and its files are in
// DIR, and then writes manifest.json, the QC page and methods.md exactly as
// a one-machine build writes them. A missing, duplicated, stale or foreign
// shard is refused naming it (InputError, every problem at once).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/shards.h"
#include "avsi/stimuli/builder.h"

namespace avsi::stimuli {

// A shard manifest's path: <out>/shards/shard-K-of-N.json.
std::filesystem::path shard_manifest_path(const std::filesystem::path& out_dir, ShardSpec shard);

// How a protocol's stimuli split into shards.
struct ShardPlan {
    std::size_t stimuli = 0;
    double expected_frames = 0.0;
    std::vector<std::size_t> stimuli_per_shard;
    std::vector<double> expected_frames_per_shard;
    std::vector<std::size_t> sentences_per_shard;  // whose speech each shard makes
};

// The split of `settings`' stimuli into `shards` shards (loads the protocol,
// its corpus, models and head; InputError as build_stimuli).
ShardPlan plan_shards(const BuildSettings& settings, std::size_t shards);

// `build-stimuli --slurm-script PATH`: checks the protocol (plan_shards),
// then writes the job array of `slurm.shards` build tasks at PATH (task K
// runs `avsi build-stimuli … --shard K/N`), the merge job (`--merge`, then
// `--verify`) and the submit script (slurm shards.h in core). `avsi` is the
// executable the tasks run; `build_options` are the build's own options
// every task and the merge repeat (--max-sentences, --lod, …). Paths are
// made absolute: the tasks run on other nodes, from a shared filesystem.
SlurmScripts write_build_slurm_scripts(const BuildSettings& settings, const SlurmSettings& slurm,
                                       const std::filesystem::path& path, const std::filesystem::path& avsi,
                                       const std::vector<std::string>& build_options);

}  // namespace avsi::stimuli
