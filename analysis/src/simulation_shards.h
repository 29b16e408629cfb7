// The shard files of the simulations run as a job array (`avsi power` and
// `avsi simulate-srt` with --shard K/N, merged by --merge; docs/cluster.md).
// A shard file is <out>/<stem>.shard-K-of-N.csv:
//
//   # avsi-power-shard 2/4
//   # avsi 0.1.0
//   # settings {"alpha":0.05,…}
//   subjects,simulation,anova,…
//   10,250,1,0,1,62.158765432098775
//
// one row per simulated replicate, every number as written by fmt's "{}"
// (the shortest text that reads back as the same double), so the merge gets
// the replicates' values bit for bit and summarises them exactly as the
// unsharded run does.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "avsi/core/shards.h"

namespace avsi::analysis::detail {

// What a kind of shard file is: its format name ("avsi-power-shard"), the
// stem of its files ("power"), its CSV columns and the command that makes a
// shard ("avsi power … ", for messages).
struct ShardKind {
    std::string format;
    std::string stem;
    std::vector<std::string> columns;
    std::string rerun;
};

// <out>/<stem>.shard-K-of-N.csv
std::filesystem::path shard_file_path(const std::filesystem::path& out_dir, const ShardKind& kind, ShardSpec shard);

// Writes a shard file: the header lines, then `rows` (CSV lines, each ending
// in a newline).
void write_shard_file(const std::filesystem::path& out_dir, const ShardKind& kind, ShardSpec shard,
                      const nlohmann::json& settings, const std::string& rows);

// One row of a shard file: its fields, its line number and a function that
// throws InputError at that line naming a column (for the caller's checks).
struct ShardRow {
    std::vector<std::string_view> fields;
    int line = 0;
    std::function<void(std::size_t column, const std::string& message)> fail;
    // The field as an integer / a double (finite) / "NA" or a double; throws through fail.
    long long integer(std::size_t column) const;
    double number(std::size_t column) const;
    bool is_na(std::size_t column) const { return fields[column] == "NA"; }
};

// Finds every shard file of the split in `out_dir` (find_shard_files: none,
// two splits or a missing shard are refused naming it), checks each one's
// header (its format; the shard it claims against its name; the avsi
// version; its settings against `settings`, naming each that differs),
// passes its rows in order to `row`, then calls `end` for the shard with a
// function that throws InputError naming the file's end (a shard cut short).
// Returns the number of shards.
std::size_t read_shard_files(const std::filesystem::path& out_dir, const ShardKind& kind,
                             const nlohmann::json& settings,
                             const std::function<void(ShardSpec shard, const ShardRow& row)>& row,
                             const std::function<void(ShardSpec shard, const std::function<void(const std::string&)>& fail)>& end);

}  // namespace avsi::analysis::detail
