// The steps of a sharded build that the builder (builder.cpp) calls: the
// split, the shard manifests and the merge's checks (shards.h says what a
// sharded build does). The builder's plan is private to builder.cpp; it
// hands these functions its stimuli as PlannedStimulus and its manifest
// entries as JSON.
#pragma once

#include <cstddef>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "avsi/core/corpus.h"
#include "avsi/core/protocol.h"
#include "avsi/core/shards.h"
#include "avsi/stimuli/shards.h"

namespace avsi::stimuli::detail {

// One stimulus of the plan, as the split and the merge see it.
struct PlannedStimulus {
    std::string sentence;          // its sentence's id (the sentence's stimuli share its speech)
    std::string path;              // <sentence>/<condition>.mp4 within the set
    std::string wav;               // its audio, within the set
    std::string input_hash;        // the manifest's input_sha256
    double expected_frames = 0.0;  // the split's weight
};

// What every shard of one plan must share; each shard manifest records it.
struct PlanIdentity {
    std::string protocol;         // the protocol's file name
    std::string protocol_sha256;  // of the protocol file
    std::string inputs_sha256;    // of every stimulus's path and input hash, in plan order
    std::string builder;          // the builder's output version
    std::string avsi;             // avsi_version()
};

PlanIdentity plan_identity(const std::filesystem::path& protocol_path, const std::vector<PlannedStimulus>& stimuli,
                           const std::string& builder_version);

// The expected length of a sentence's speech, in seconds, for the split:
// the end of its last phone label for recordings; for synthesised speech an
// estimate from the text (0.5 s + 1/14 s per letter, about the rate of the
// project's voices), since the speech is not made before the build.
double expected_duration_s(const Sentence& sentence, const Protocol& protocol);

// Whether each stimulus is in `shard`: the split by expected frames, a
// sentence's stimuli together unless they weigh more than a quarter of a
// shard's share (assign_grouped_shards).
std::vector<bool> shard_members(const std::vector<PlannedStimulus>& stimuli, ShardSpec shard);

// The split's totals (plan_shards).
ShardPlan shard_plan(const std::vector<PlannedStimulus>& stimuli, std::size_t shards);

// The entries of the shard's earlier manifest by path (what a re-run may
// reuse); none when there is none or it cannot be read.
std::map<std::string, nlohmann::json> shard_entries(const std::filesystem::path& out_dir, ShardSpec shard);

// Writes <out>/shards/shard-K-of-N.json with the identity and the entries of
// the shard's stimuli.
void write_shard_manifest(const std::filesystem::path& out_dir, ShardSpec shard, const PlanIdentity& identity,
                          const std::vector<nlohmann::json>& entries);

// Reads every shard manifest in <out>/shards and returns each planned
// stimulus's entry, in plan order, after the checks of the merge
// (shards.h). Throws InputError naming each shard file and stimulus at
// fault, all at once.
std::vector<nlohmann::json> merge_shard_entries(const std::filesystem::path& out_dir, const PlanIdentity& identity,
                                                const std::vector<PlannedStimulus>& stimuli);

}  // namespace avsi::stimuli::detail
