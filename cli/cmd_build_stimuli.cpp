// `avsi build-stimuli`: every sentence × condition of a protocol rendered
// to MP4 with its audio, in parallel, skipping unchanged stimuli; writes
// manifest.json. On a cluster: one shard of the set (--shard K/N), the merge
// of the shards (--merge), or the Slurm job array that runs them
// (--slurm-script; docs/cluster.md).
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/shards.h"
#include "command.h"
#include "lod_options.h"
#include "shard_options.h"

namespace avsi::cli {
namespace {

int verify(const stimuli::BuildSettings& o) {
    const stimuli::VerifyReport r = stimuli::verify_stimuli(o);
    for (const auto& line : r.problems) fmt::print(stderr, "{}: {}\n", o.out_dir.string(), line);
    if (!r.extra.empty())
        fmt::print("note: {} more stimuli in the manifest that this protocol does not ask for (built with "
                   "--all-sentences, or for an earlier protocol), e.g. {}\n",
                   r.extra.size(), r.extra.front());
    if (r.problems.empty()) {
        fmt::print("verified {} stimuli in {}: all match the protocol and the manifest\n", r.total,
                   o.out_dir.string());
        return 0;
    }
    fmt::print(stderr, "{} of {} stimuli verified; {} problem(s) above\n", r.verified, r.total, r.problems.size());
    return 1;
}

struct SlurmOptions {
    std::filesystem::path script;
    SlurmSettings settings;
    std::filesystem::path avsi;
};

// The build's own options, repeated by every task and the merge of a Slurm array.
const std::vector<std::string> build_option_names = {"--max-sentences", "--all-sentences", "--force", "--lod",
                                                     "--max-triangles", "--lod-error-px"};

int write_slurm(const stimuli::BuildSettings& o, const SlurmOptions& slurm, const CLI::App& sub) {
    const SlurmScripts s = stimuli::write_build_slurm_scripts(
        o, slurm.settings, slurm.script, slurm.avsi.empty() ? front_end_executable() : slurm.avsi,
        given_options(sub, build_option_names));
    fmt::print("written: {} ({} build tasks), {} (the merge and --verify), {}\nsubmit with: {}\n", s.array.string(),
               slurm.settings.shards, s.merge.string(), s.submit.string(), s.submit.string());
    return 0;
}

const bool registered_build_stimuli = register_command({
    "build-stimuli",
    "Build the stimulus videos of a protocol (sentence x condition) with a manifest",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<stimuli::BuildSettings>();
        sub.add_option("protocol", o->protocol_path, "Protocol file (TOML)")->required();
        sub.add_option("--out", o->out_dir, "Output folder")->required();
        sub.add_option("--jobs", o->jobs, "Worker threads (0 = one per core)")->capture_default_str();
        sub.add_flag("--force", o->force, "Rebuild every stimulus even if unchanged");
        sub.add_option("--max-sentences", o->max_sentences, "Only the first N sentences (0 = all)")
            ->capture_default_str();
        sub.add_flag("--all-sentences", o->all_sentences,
                     "Build every sentence x condition; by default, when the corpus assigns lists, spare "
                     "sentences are skipped and warm-up/practice sentences are built only in the conditions "
                     "the design shows them in");
        const auto parse_lod = add_lod_options(sub, o->lod, "; recorded in the manifest");
        auto verify_flag = std::make_shared<bool>(false);
        auto* verify_option = sub.add_flag(
            "--verify", *verify_flag,
            "Build nothing; check the set in --out against the protocol and manifest.json: every stimulus "
            "present, up to date, with the manifest's SHA-256, decoding to its frame count and rate with "
            "audio as long as the video. Exit status 1 if anything is wrong");
        const auto parse_shard = add_shard_options(
            sub, o->shard, o->merge,
            "Build only shard K of N of the stimuli (split by expected frame count, the same on every node) and "
            "write --out/shards/shard-K-of-N.json instead of manifest.json",
            "Build nothing; merge the shard manifests in --out/shards into manifest.json, the QC page and "
            "methods.md, as a one-machine build writes them; refuses a missing, duplicated, stale or foreign "
            "shard, naming it");
        verify_option->excludes(sub.get_option("--shard"))->excludes(sub.get_option("--merge"));
        auto slurm = std::make_shared<SlurmOptions>();
        auto* script = add_slurm_options(sub, slurm->script, slurm->settings, slurm->avsi,
                                         "--shards build tasks of --shard K/N, then --merge and --verify");
        script->excludes(verify_option)->excludes(sub.get_option("--shard"))->excludes(sub.get_option("--merge"));
        return [o, verify_flag, slurm, parse_lod, parse_shard, &sub] {
            parse_lod();
            parse_shard();
            if (!slurm->script.empty()) return write_slurm(*o, *slurm, sub);
            if (*verify_flag) return verify(*o);
            stimuli::build_stimuli(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
