// The options of commands that split their work for a cluster
// (docs/cluster.md): --shard K/N and --merge (build-stimuli, simulate-srt,
// power), and --slurm-script with the resources each task asks for.
// Header-only (CLI11 and avsi_core, which every helper links).
#pragma once

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "avsi/core/error.h"
#include "avsi/core/executable_folder.h"
#include "avsi/core/shards.h"

namespace avsi::cli {

// A CLI11 check of a K/N value (parse_shard): a bad one fails when the line
// is parsed, with exit status 2.
inline CLI::Validator shard_value() {
    return CLI::Validator(
        [](std::string& value) -> std::string {
            try {
                parse_shard(value);
                return {};
            } catch (const InputError& e) {
                return e.first().message;
            }
        },
        "K/N", "shard");
}

// --shard K/N and --merge, exclusive; `merge_help` says what the merge
// writes. Returns the function that puts --shard into `shard` once the line
// is parsed (`shard` must outlive it).
inline std::function<void()> add_shard_options(CLI::App& sub, ShardSpec& shard, bool& merge,
                                               const std::string& shard_help, const std::string& merge_help) {
    auto text = std::make_shared<std::string>();
    auto* shard_option =
        sub.add_option("--shard", *text,
                       shard_help + "; K counts from 0 (Slurm's SLURM_ARRAY_TASK_ID), so the shards of N are 0/N … "
                                    "(N-1)/N (docs/cluster.md)")
            ->check(shard_value());
    sub.add_flag("--merge", merge, merge_help)->excludes(shard_option);
    return [text, &shard] {
        if (!text->empty()) shard = parse_shard(*text);
    };
}

// --slurm-script PATH and the resources of each task: --shards, --time,
// --mem, --cpus, and --avsi (the executable the tasks run). Returns the
// --slurm-script option (the others need it).
inline CLI::Option* add_slurm_options(CLI::App& sub, std::filesystem::path& script, SlurmSettings& slurm,
                                      std::filesystem::path& avsi, const std::string& what) {
    auto* option = sub.add_option("--slurm-script", script,
                                  "Write a Slurm job array to this path instead of running: " + what +
                                      "; beside it <stem>.merge.sbatch (the merge, after every task succeeded) and "
                                      "<stem>.submit.sh, which submits both (docs/cluster.md)");
    sub.add_option("--shards", slurm.shards, "With --slurm-script: the number of array tasks (shards)")
        ->capture_default_str()
        ->needs(option);
    sub.add_option("--time", slurm.time, "With --slurm-script: each task's time limit (sbatch --time)")
        ->capture_default_str()
        ->needs(option);
    sub.add_option("--mem", slurm.mem, "With --slurm-script: each task's memory (sbatch --mem, e.g. 4G)")
        ->capture_default_str()
        ->needs(option);
    sub.add_option("--cpus", slurm.cpus, "With --slurm-script: each task's CPUs (sbatch --cpus-per-task; its --jobs)")
        ->capture_default_str()
        ->needs(option);
    sub.add_option("--avsi", avsi,
                   "With --slurm-script: the avsi executable the tasks run, as the nodes see it (default: this one)")
        ->needs(option);
    return option;
}

// The avsi front end beside this helper: build/cli/avsi for the build tree
// (helpers in build/cli/libexec), <prefix>/bin/avsi for an installed one
// (helpers in <prefix>/libexec/avsi); "avsi" (from PATH) when neither is there.
inline std::filesystem::path front_end_executable() {
    const std::filesystem::path helpers = executable_folder();
    for (const auto& candidate : {helpers.parent_path() / "avsi", helpers.parent_path().parent_path() / "bin" / "avsi"})
        if (!helpers.empty() && std::filesystem::is_regular_file(candidate) && ::access(candidate.c_str(), X_OK) == 0)
            return candidate;
    return "avsi";
}

// The values of the options named in `names` that were given, as arguments
// to repeat (name, then its values; a flag alone); the values of those in
// `paths` made absolute (the tasks may start in another folder).
inline std::vector<std::string> given_options(const CLI::App& sub, const std::vector<std::string>& names,
                                              const std::vector<std::string>& paths = {}) {
    std::vector<std::string> args;
    for (const std::string& name : names) {
        const CLI::Option* o = sub.get_option_no_throw(name);
        if (o == nullptr || o->count() == 0) continue;
        args.push_back(name);
        if (o->get_type_size() != 0)
            for (const std::string& value : o->results())
                args.push_back(std::find(paths.begin(), paths.end(), name) == paths.end()
                                   ? value
                                   : std::filesystem::absolute(value).lexically_normal().string());
    }
    return args;
}

// --slurm-script for a simulation command (simulate-srt, power): the array's
// tasks run `avsi <command> <the options given> --shard K/N --out OUT`
// (`threads`, when not empty, set to the task's CPUs), the merge job the
// same with --merge. Prints what it wrote.
inline int write_simulation_slurm_scripts(const CLI::App& sub, const std::string& command,
                                          const std::vector<std::string>& options, const std::string& threads,
                                          const std::filesystem::path& out, const std::filesystem::path& script,
                                          const SlurmSettings& slurm, const std::filesystem::path& avsi) {
    if (out.empty()) throw UsageError("--slurm-script needs --out: the shared folder of the shards and the merge");
    const std::filesystem::path folder = std::filesystem::absolute(out).lexically_normal();
    std::vector<std::string> head = {(avsi.empty() ? front_end_executable() : avsi).string(), command};
    const std::vector<std::string> given = given_options(sub, options, {"--protocol"});
    head.insert(head.end(), given.begin(), given.end());
    head.insert(head.end(), {"--out", folder.string()});
    if (!threads.empty()) head.insert(head.end(), {threads, "{cpus}"});
    SlurmJob job;
    job.name = "avsi-" + command;
    job.what = fmt::format("avsi {} in {} shards, into {}", command, slurm.shards, folder.string());
    job.log_dir = folder / "slurm";
    job.task = head;
    job.task.insert(job.task.end(), {"--shard", "{shard}"});
    job.merge = {head};
    job.merge.front().push_back("--merge");
    const SlurmScripts s = write_slurm_scripts(script, job, slurm);
    fmt::print("written: {} ({} tasks), {} (the merge), {}\nsubmit with: {}\n", s.array.string(), slurm.shards,
               s.merge.string(), s.submit.string(), s.submit.string());
    return 0;
}

}  // namespace avsi::cli
