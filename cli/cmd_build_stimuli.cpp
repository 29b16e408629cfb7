// `avsi build-stimuli`: every sentence × condition of a protocol rendered
// to MP4 with its audio, in parallel, skipping unchanged stimuli; writes
// manifest.json.
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/stimuli/builder.h"
#include "command.h"
#include "lod_options.h"

namespace avsi::cli {
namespace {

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
        auto verify = std::make_shared<bool>(false);
        sub.add_flag("--verify", *verify,
                     "Build nothing; check the set in --out against the protocol and manifest.json: every stimulus "
                     "present, up to date, with the manifest's SHA-256, decoding to its frame count and rate with "
                     "audio as long as the video. Exit status 1 if anything is wrong");
        return [o, verify, parse_lod] {
            parse_lod();
            if (!*verify) {
                stimuli::build_stimuli(*o);
                return 0;
            }
            const stimuli::VerifyReport r = stimuli::verify_stimuli(*o);
            for (const auto& line : r.problems) fmt::print(stderr, "{}: {}\n", o->out_dir.string(), line);
            if (!r.extra.empty())
                fmt::print("note: {} more stimuli in the manifest that this protocol does not ask for (built with "
                           "--all-sentences, or for an earlier protocol), e.g. {}\n",
                           r.extra.size(), r.extra.front());
            if (r.problems.empty()) {
                fmt::print("verified {} stimuli in {}: all match the protocol and the manifest\n", r.total,
                           o->out_dir.string());
                return 0;
            }
            fmt::print(stderr, "{} of {} stimuli verified; {} problem(s) above\n", r.verified, r.total,
                       r.problems.size());
            return 1;
        };
    }});

}  // namespace
}  // namespace avsi::cli
