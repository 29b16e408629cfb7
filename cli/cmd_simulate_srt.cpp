// `avsi simulate-srt`: an adaptive SRT procedure against simulated listeners
// (logistic psychometric function, word-level binomial responses) — bias and
// spread of the SRT estimate by track length, to choose the list length.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/analysis/adaptive.h"
#include "avsi/core/error.h"
#include "avsi/core/protocol.h"
#include "command.h"
#include "shard_options.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

struct SimulateSrtOptions {
    std::string protocol, procedure = "sentence", out;
    std::vector<int> sentences = {10, 15, 20, 25, 30};
    double l50_db = -6.0, slope = 0.15, start_sd_db = 2.0, ceiling = 1.0;
    std::optional<double> assumed_slope;
    bool include_unconverged = false;
    int keywords = 3, listeners = 1000;
    std::uint64_t seed = 1;
    ShardSpec shard;
    bool merge = false;
    std::filesystem::path slurm_script, avsi;
    SlurmSettings slurm;
};

// The options a Slurm array's tasks and merge repeat (all but --out and the Slurm ones).
const std::vector<std::string> srt_option_names = {
    "--protocol", "--procedure", "--l50-db", "--slope", "--ceiling", "--assumed-slope", "--include-unconverged",
    "--keywords", "--sentences", "--listeners", "--start-sd", "--seed"};

int run_simulate_srt(const SimulateSrtOptions& o, bool procedure_given, const CLI::App& sub) {
    analysis::SrtSimulationSettings s;
    if (!o.protocol.empty()) {
        const Protocol protocol = load_protocol(o.protocol);
        const analysis::AdaptiveProtocol a = analysis::adaptive_protocol(protocol);
        if (!a.enabled)
            throw InputError(o.protocol, 0, 0, "adaptive", "expected an [adaptive] section: the protocol runs no adaptive tracks");
        if (procedure_given) throw UsageError("--procedure: the protocol's [adaptive] section sets the procedure");
        if (a.list_variable())
            throw InputError(o.protocol, protocol.adaptive.line(), 0, "adaptive.variable",
                             fmt::format("expected \"snr\": simulate-srt models listeners by a psychometric function "
                                         "of the SNR in dB; a \"{}\" track (levels on a list) is not simulated",
                                         analysis::to_string(a.variable)));
        s.track = a.track;
        if (o.assumed_slope) throw UsageError("--assumed-slope: the protocol's [adaptive] slope_per_db sets it");
    } else {
        s.track.procedure = o.procedure == "word" ? analysis::AdaptiveProcedure::Word : analysis::AdaptiveProcedure::Sentence;
        if (o.assumed_slope) s.track.slope_per_db = *o.assumed_slope;
    }
    s.listener.ceiling = o.ceiling;
    s.include_unconverged = o.include_unconverged;
    s.listener.l50_db = o.l50_db;
    s.listener.slope_per_db = o.slope;
    s.listener.keywords = o.keywords;
    s.sentence_counts = o.sentences;
    s.listeners = o.listeners;
    s.seed = o.seed;
    s.start_offset_sd_db = o.start_sd_db;
    if (!o.slurm_script.empty())
        return write_simulation_slurm_scripts(sub, "simulate-srt", srt_option_names, "", o.out,
                                              o.slurm_script, o.slurm, o.avsi);
    if ((o.shard.sharded() || o.merge) && o.out.empty())
        throw UsageError("--shard and --merge need --out: the folder of the shard files");
    if (o.shard.sharded()) {
        analysis::simulate_srt_shard(s, o.shard, o.out);
        return 0;
    }
    const auto result = o.merge ? analysis::merge_srt_shards(s, o.out) : analysis::simulate_srt(s);
    fmt::print("{}", analysis::srt_simulation_table(result));
    if (!o.out.empty()) {
        analysis::write_srt_simulation(o.out, result);
        fmt::print("written: {}/srt_simulation.csv, {}/srt_simulation.png\n", o.out, o.out);
    }
    return 0;
}

const bool registered_simulate_srt = register_command({
    "simulate-srt",
    "Bias and spread of adaptive SRT estimates by track length, against simulated listeners",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<SimulateSrtOptions>();
        sub.add_option("--protocol", o->protocol, "Take the procedure and its rules from this protocol's [adaptive] section")
            ->check(CLI::ExistingFile);
        auto* procedure = sub.add_option("--procedure", o->procedure,
                                         "Without --protocol: sentence (1-up/1-down, HINT steps) or word (Brand & "
                                         "Kollmeier 2002) with the default rules")
                              ->check(one_of({to_string(analysis::AdaptiveProcedure::Sentence),
                                              to_string(analysis::AdaptiveProcedure::Word)}))
                              ->capture_default_str();
        sub.add_option("--l50-db", o->l50_db, "The listener's keyword L50 (dB SNR)")->capture_default_str();
        sub.add_option("--slope", o->slope, "The listener's keyword slope at L50 (proportion per dB)")
            ->capture_default_str();
        sub.add_option("--ceiling", o->ceiling,
                       "The listener's upper asymptote: the proportion of keywords right at the easiest level "
                       "(1 − lapse rate), in (0, 1]")
            ->capture_default_str();
        sub.add_option("--assumed-slope", o->assumed_slope,
                       "Without --protocol: the slope (proportion per dB) word scoring's step rule assumes "
                       "(default 0.15), independent of the listener's --slope");
        sub.add_flag("--include-unconverged", o->include_unconverged,
                     "Keep tracks that hit a bound or did not reverse in the estimates (default: counted, left out)");
        sub.add_option("--keywords", o->keywords, "Keywords per sentence")->capture_default_str();
        sub.add_option("--sentences", o->sentences, "Track lengths (sentences), comma-separated")
            ->delimiter(',')
            ->capture_default_str();
        sub.add_option("--listeners", o->listeners, "Simulated listeners per track length")->capture_default_str();
        sub.add_option("--start-sd", o->start_sd_db, "SD of the start level around the protocol's (dB)")
            ->capture_default_str();
        sub.add_option("--seed", o->seed, "Random seed")->capture_default_str();
        sub.add_option("--out", o->out, "Folder for srt_simulation.csv and srt_simulation.png (default: print only)");
        const auto parse_shard = add_shard_options(
            sub, o->shard, o->merge,
            "Simulate only shard K of N: for every track length its contiguous share of the --listeners, each "
            "with the seed it has in the whole run; writes --out/srt_simulation.shard-K-of-N.csv",
            "Simulate nothing; merge the shard files in --out into the table, srt_simulation.csv and .png the "
            "whole run gives, number for number (give the options the shards were run with)");
        add_slurm_options(sub, o->slurm_script, o->slurm, o->avsi, "--shards tasks of --shard K/N, then --merge")
            ->excludes(sub.get_option("--shard"))
            ->excludes(sub.get_option("--merge"));
        return [o, procedure, parse_shard, &sub] {
            parse_shard();
            return run_simulate_srt(*o, procedure->count() > 0, sub);
        };
    }});

}  // namespace
}  // namespace avsi::cli
