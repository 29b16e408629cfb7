// `avsi power`: power of the repeated-measures ANOVA and of one pairwise LSD
// contrast over subject counts, by simulation (a planning aid).
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/analysis/power.h"
#include "command.h"
#include "shard_options.h"

namespace avsi::cli {
namespace {

struct PowerOptions {
    std::string means, subjects = "10..40", contrast, out;
    std::size_t sentences_per_cell = 15, keywords = 3, sims = 1000, threads = 0;
    double subject_sd = 0.5, sentence_sd = 0.5, alpha = 0.05, condition_sd = analysis::kConditionSdDefault;
    std::uint64_t seed = 1;
    ShardSpec shard;
    bool merge = false;
    std::filesystem::path slurm_script, avsi;
    SlurmSettings slurm;
};

// The options a Slurm array's tasks and merge repeat (all but --out, --threads and the Slurm ones).
const std::vector<std::string> power_option_names = {
    "--means", "--subjects", "--sentences-per-cell", "--keywords", "--subject-sd", "--sentence-sd",
    "--condition-sd", "--sims", "--seed", "--contrast", "--alpha"};

int run_power(const PowerOptions& o, const CLI::App& sub) {
    analysis::PowerSettings s;
    s.means_percent = analysis::parse_means(o.means);
    s.subject_counts = analysis::parse_subject_counts(o.subjects);
    s.sentences_per_cell = o.sentences_per_cell;
    s.keywords_per_sentence = o.keywords;
    s.subject_sd = o.subject_sd;
    s.condition_sd = o.condition_sd;
    s.sentence_sd = o.sentence_sd;
    s.simulations = o.sims;
    s.seed = o.seed;
    s.alpha = o.alpha;
    s.threads = o.threads;
    if (!o.contrast.empty()) {
        const auto [a, b] = analysis::parse_contrast(o.contrast, s.means_percent.size());
        s.contrast_a = a;
        s.contrast_b = b;
    }
    if (!o.slurm_script.empty())
        return write_simulation_slurm_scripts(sub, "power", power_option_names, "--threads", o.out,
                                              o.slurm_script, o.slurm, o.avsi);
    if ((o.shard.sharded() || o.merge) && o.out.empty())
        throw UsageError("--shard and --merge need --out: the folder of the shard files");
    if (o.shard.sharded()) {
        analysis::simulate_power_shard(s, o.shard, o.out);
        return 0;
    }
    const auto result = o.merge ? analysis::merge_power_shards(s, o.out) : analysis::simulate_power(s);
    fmt::print("{}", analysis::power_table(result));
    if (!o.out.empty()) analysis::write_power_files(o.out, result);
    return 0;
}

const bool registered_power = register_command({
    "power",
    "Power of the ANOVA and of a pairwise LSD contrast over subject counts, by simulation",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<PowerOptions>();
        sub.add_option("--means", o->means, "Expected percent correct per condition, e.g. 60,70,72,75,78,80")
            ->required();
        sub.add_option("--subjects", o->subjects, "Subject counts: low..high (step 5), low..high:step or a,b,c")
            ->capture_default_str();
        sub.add_option("--sentences-per-cell", o->sentences_per_cell, "Sentences per subject and condition")
            ->capture_default_str()
            ->check(CLI::Range(1, 10000));
        sub.add_option("--keywords", o->keywords, "Scored keywords per sentence")
            ->capture_default_str()
            ->check(CLI::Range(1, 100));
        sub.add_option("--subject-sd", o->subject_sd, "SD of subject random effects (logit scale)")
            ->capture_default_str();
        sub.add_option("--sentence-sd", o->sentence_sd, "SD of sentence random effects (logit scale)")
            ->capture_default_str();
        sub.add_option("--condition-sd", o->condition_sd,
                       "SD of subject x condition random slopes (logit scale; the default is derived from MacLeod & "
                       "Summerfield 1987, stated in the output; 0: no random slopes)")
            ->capture_default_str();
        sub.add_option("--sims", o->sims, "Simulated experiments per subject count")
            ->capture_default_str()
            ->check(CLI::Range(1, 10000000));
        sub.add_option("--seed", o->seed, "Random seed")->capture_default_str();
        sub.add_option("--contrast", o->contrast, "Pairwise contrast a-b by condition number (default: last-first)");
        sub.add_option("--alpha", o->alpha, "Significance level")->capture_default_str();
        sub.add_option("--threads", o->threads, "Worker threads (0: all cores)")->capture_default_str();
        sub.add_option("--out", o->out, "Folder for power.csv, power.json and power.txt (default: print only)");
        const auto parse_shard = add_shard_options(
            sub, o->shard, o->merge,
            "Simulate only shard K of N: for every subject count its contiguous share of the --sims experiments, "
            "each with the seed it has in the whole run; writes --out/power.shard-K-of-N.csv",
            "Simulate nothing; merge the shard files in --out into the table, power.csv, power.json and power.txt "
            "the whole run gives, number for number (give the options the shards were run with)");
        add_slurm_options(sub, o->slurm_script, o->slurm, o->avsi, "--shards tasks of --shard K/N, then --merge")
            ->excludes(sub.get_option("--shard"))
            ->excludes(sub.get_option("--merge"));
        return [o, parse_shard, &sub] {
            parse_shard();
            return run_power(*o, sub);
        };
    }});

}  // namespace
}  // namespace avsi::cli
