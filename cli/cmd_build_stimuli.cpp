// `avsi build-stimuli`: every sentence × condition of a protocol rendered
// to MP4 with its audio, in parallel, skipping unchanged stimuli; writes
// manifest.json.
#include <memory>

#include "avsi/stimuli/builder.h"
#include "command.h"

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
        return [o] {
            stimuli::build_stimuli(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
