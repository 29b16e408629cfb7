// Shards and their Slurm scripts (see shards.h).
#include "avsi/core/shards.h"

#include <sys/stat.h>

#include <algorithm>
#include <map>
#include <numeric>
#include <regex>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi {

// AVSI_VERSION: the project's version, set for this file alone (core/CMakeLists.txt).
std::string avsi_version() { return AVSI_VERSION; }

std::string ShardSpec::text() const { return fmt::format("{}/{}", index, count); }

std::string ShardSpec::stem() const { return fmt::format("shard-{}-of-{}", index, count); }

ShardSpec parse_shard(const std::string& text, const std::string& option) {
    const auto fail = [&](const std::string& why) {
        throw InputError("", 0, 0, option,
                         fmt::format("expected K/N with 0 <= K < N <= {} (K counts from 0, as SLURM_ARRAY_TASK_ID "
                                     "does){}, got \"{}\"",
                                     max_shards, why, text));
    };
    const std::size_t slash = text.find('/');
    if (slash == std::string::npos) fail("");
    const auto k = parse_int(text.substr(0, slash));
    const auto n = parse_int(text.substr(slash + 1));
    if (!k || !n || *k < 0 || *n < 1 || *n > static_cast<long long>(max_shards)) fail("");
    if (*k >= *n) fail(fmt::format(": the last of {} shards is {}/{}", *n, *n - 1, *n));
    return {static_cast<std::size_t>(*k), static_cast<std::size_t>(*n)};
}

std::pair<std::size_t, std::size_t> shard_range(std::size_t total, ShardSpec shard) {
    if (!shard.sharded()) return {0, total};
    // K·total/N without overflow for any total below 2^64 / max_shards.
    const auto bound = [&](std::size_t k) { return total / shard.count * k + total % shard.count * k / shard.count; };
    return {bound(shard.index), bound(shard.index + 1)};
}

std::vector<std::size_t> assign_shards(const std::vector<double>& weights, std::size_t shards) {
    std::vector<std::size_t> order(weights.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return weights[a] > weights[b]; });
    std::vector<double> load(std::max<std::size_t>(shards, 1), 0.0);
    std::vector<std::size_t> shard_of(weights.size(), 0);
    for (const std::size_t item : order) {
        const std::size_t least =
            static_cast<std::size_t>(std::min_element(load.begin(), load.end()) - load.begin());  // first of equals
        shard_of[item] = least;
        load[least] += weights[item];
    }
    return shard_of;
}

std::vector<std::size_t> assign_grouped_shards(const std::vector<double>& weights,
                                               const std::vector<std::size_t>& group_of, std::size_t shards) {
    AVSI_ASSERT(group_of.size() == weights.size());
    const double total = std::accumulate(weights.begin(), weights.end(), 0.0);
    const double whole_up_to = total / double(std::max<std::size_t>(shards, 1)) / 4.0;
    std::map<std::size_t, double> group_weight;
    for (std::size_t i = 0; i < weights.size(); ++i) group_weight[group_of[i]] += weights[i];
    // The units: a light group as one, each item of a heavy group alone.
    std::vector<std::size_t> unit_of(weights.size());
    std::vector<double> unit_weight;
    std::map<std::size_t, std::size_t> unit_of_group;
    for (std::size_t i = 0; i < weights.size(); ++i) {
        if (group_weight[group_of[i]] <= whole_up_to) {
            const auto [it, added] = unit_of_group.emplace(group_of[i], unit_weight.size());
            if (added) unit_weight.push_back(0.0);
            unit_of[i] = it->second;
            unit_weight[it->second] += weights[i];
        } else {
            unit_of[i] = unit_weight.size();
            unit_weight.push_back(weights[i]);
        }
    }
    const std::vector<std::size_t> shard_of_unit = assign_shards(unit_weight, shards);
    std::vector<std::size_t> shard_of(weights.size());
    for (std::size_t i = 0; i < weights.size(); ++i) shard_of[i] = shard_of_unit[unit_of[i]];
    return shard_of;
}

ShardFiles find_shard_files(const std::filesystem::path& dir, const std::string& prefix, const std::string& suffix,
                            const std::string& rerun) {
    const std::regex name("^" + std::regex_replace(prefix, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") +
                          R"(shard-(\d+)-of-(\d+))" +
                          std::regex_replace(suffix, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") + "$");
    std::map<std::size_t, std::map<std::size_t, std::filesystem::path>> splits;  // N → K → file
    std::error_code ec;
    if (std::filesystem::is_directory(dir, ec))
        for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
            const std::string file = entry.path().filename().string();
            std::smatch m;
            if (!std::regex_match(file, m, name)) continue;
            const auto k = parse_int(m[1].str()), n = parse_int(m[2].str());
            if (!k || !n || *n < 1 || *k >= *n || *n > static_cast<long long>(max_shards)) continue;
            splits[static_cast<std::size_t>(*n)][static_cast<std::size_t>(*k)] = entry.path();
        }
    const std::string pattern = (dir / (prefix + "shard-K-of-N" + suffix)).string();
    if (splits.empty())
        throw InputError(dir, fmt::format("no shard files ({}): run {} --shard K/N for K = 0 … N-1 first", pattern,
                                          rerun));
    if (splits.size() > 1) {
        std::string counts;
        for (const auto& [n, files] : splits)
            counts += fmt::format("{}{} of {} ({}…)", counts.empty() ? "" : "; ", files.size(), n,
                                  files.begin()->second.filename().string());
        throw InputError(dir, fmt::format("shard files of {} different splits: {}; remove the files of the splits "
                                          "that are not meant, then merge again",
                                          splits.size(), counts));
    }
    ShardFiles found;
    found.count = splits.begin()->first;
    const auto& present = splits.begin()->second;
    DiagnosticList problems;
    for (std::size_t k = 0; k < found.count; ++k) {
        const auto it = present.find(k);
        if (it != present.end()) {
            found.files.push_back(it->second);
            continue;
        }
        const ShardSpec missing{k, found.count};
        problems.add((dir / (prefix + missing.stem() + suffix)).string(), 0, 0, "shard " + missing.text(),
                     fmt::format("missing: shard {} of {} was not built (or its task failed); run {} --shard {}", k,
                                 found.count, rerun, missing.text()));
    }
    problems.throw_if_any();
    return found;
}

void validate_slurm_settings(const SlurmSettings& s) {
    DiagnosticList problems;
    if (s.shards < 1 || s.shards > max_shards)
        problems.add("", 0, 0, "--shards", fmt::format("expected a count in [1, {}], got {}", max_shards, s.shards));
    static const std::regex time(R"(^(\d+|\d+:\d{1,2}|\d+:\d{1,2}:\d{1,2}|\d+-\d+|\d+-\d+:\d{1,2}|\d+-\d+:\d{1,2}:\d{1,2})$)");
    if (!std::regex_match(s.time, time))
        problems.add("", 0, 0, "--time",
                     fmt::format("expected a Slurm time limit: MM, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS, got "
                                 "\"{}\"",
                                 s.time));
    static const std::regex mem(R"(^[1-9]\d*[KMGT]?$)");
    if (!std::regex_match(s.mem, mem))
        problems.add("", 0, 0, "--mem",
                     fmt::format("expected memory per task as Slurm reads it: a count with an optional unit K, M, G "
                                 "or T (megabytes without one), e.g. 4G, got \"{}\"",
                                 s.mem));
    if (s.cpus < 1 || s.cpus > 1024)
        problems.add("", 0, 0, "--cpus", fmt::format("expected CPUs per task in [1, 1024], got {}", s.cpus));
    problems.throw_if_any();
}

namespace {

// `s` in single quotes for the shell.
std::string quote(const std::string& s) {
    std::string out = "'";
    for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

std::string command_line(const std::vector<std::string>& args, const SlurmSettings& s) {
    std::string line;
    for (const std::string& a : args) {
        line += line.empty() ? "" : " ";
        if (a == "{shard}") line += fmt::format("\"${{SLURM_ARRAY_TASK_ID}}/{}\"", s.shards);
        else if (a == "{cpus}") line += fmt::format("\"${{SLURM_CPUS_PER_TASK:-{}}}\"", s.cpus);
        else line += quote(a);
    }
    return line;
}

// The #SBATCH lines every job of the split shares.
std::string resources(const SlurmSettings& s) {
    return fmt::format("#SBATCH --cpus-per-task={}\n#SBATCH --mem={}\n#SBATCH --time={}\n", s.cpus, s.mem, s.time);
}

void write_script(const std::filesystem::path& path, const std::string& text) {
    write_text_file(path, text);
    ::chmod(path.c_str(), 0755);
}

}  // namespace

SlurmScripts write_slurm_scripts(const std::filesystem::path& path, const SlurmJob& job, const SlurmSettings& s) {
    validate_slurm_settings(s);
    static const std::regex job_name(R"(^[A-Za-z0-9._-]+$)");
    if (!std::regex_match(job.name, job_name))
        throw InputError("", 0, 0, "job name",
                         fmt::format("expected letters, digits, '.', '_' or '-', got \"{}\"", job.name));
    const std::filesystem::path logs = std::filesystem::absolute(job.log_dir).lexically_normal();
    if (logs.string().find_first_of(" \t\n%\"'") != std::string::npos)
        throw InputError(logs, "the log folder's path has a space, quote or '%', which an #SBATCH line cannot hold; "
                               "choose an --out without them");
    SlurmScripts out;
    out.array = std::filesystem::absolute(path).lexically_normal();
    const std::string stem = out.array.extension() == ".sbatch" ? out.array.stem().string() : out.array.filename().string();
    out.merge = out.array.parent_path() / (stem + ".merge.sbatch");
    out.submit = out.array.parent_path() / (stem + ".submit.sh");
    std::filesystem::create_directories(logs);

    write_script(out.array,
                 fmt::format("#!/bin/bash\n# {}\n"
                             "# A Slurm job array written by avsi (docs/cluster.md): task K of {} runs shard K/{}.\n"
                             "# Submit with {} (this array, then {} once every task has succeeded).\n"
                             "# Re-run failed tasks only: sbatch --array=K,K,... {}\n"
                             "#SBATCH --job-name={}\n#SBATCH --array=0-{}\n{}#SBATCH --output={}/%x-%A_%a.log\n"
                             "set -euo pipefail\n"
                             "if [[ -z \"${{SLURM_ARRAY_TASK_ID:-}}\" ]]; then\n"
                             "  echo \"$0: one task of a Slurm job array: submit it with sbatch, or run {}\" >&2\n"
                             "  exit 2\nfi\nexec {}\n",
                             job.what, s.shards, s.shards, out.submit.string(), out.merge.filename().string(),
                             out.array.string(), job.name, s.shards - 1, resources(s), logs.string(),
                             out.submit.string(), command_line(job.task, s)));
    std::string merge_commands;
    for (const auto& command : job.merge) merge_commands += command_line(command, s) + "\n";
    write_script(out.merge, fmt::format("#!/bin/bash\n# {}.\n# The merge of the {} shards of {}, once every task has succeeded.\n"
                                        "# Submitted by {} with --dependency=afterok:<array job id>.\n"
                                        "#SBATCH --job-name={}-merge\n{}#SBATCH --output={}/%x-%j.log\n"
                                        "set -euo pipefail\n{}",
                                        job.what, s.shards, out.array.filename().string(), out.submit.string(),
                                        job.name, resources(s), logs.string(), merge_commands));
    write_script(out.submit,
                 fmt::format("#!/bin/sh\n# Submits {} ({} tasks), then {}, which Slurm starts once every task of\n"
                             "# the array has succeeded (afterok). Arguments go to both sbatch calls, e.g.\n"
                             "# --partition=NAME --account=NAME.\nset -eu\n"
                             "array=$(sbatch --parsable \"$@\" {})\narray=${{array%%;*}}\n"
                             "merge=$(sbatch --parsable \"$@\" --dependency=afterok:\"$array\" {})\n"
                             "merge=${{merge%%;*}}\n"
                             "echo \"array job $array: {} tasks, logs in {}\"\n"
                             "echo \"merge job $merge: starts when every task of $array has succeeded\"\n"
                             "echo \"follow with: squeue -j $array,$merge (afterwards: sacct -j $array,$merge)\"\n",
                             out.array.filename().string(), s.shards, out.merge.filename().string(),
                             quote(out.array.string()), quote(out.merge.string()), s.shards, logs.string()));
    return out;
}

}  // namespace avsi
