// `avsi evaluate`: scores control models against a corpus' measured
// trajectories in the layout of Table 2 of the reference study, and plots one
// utterance like its Fig. 5 (learn/evaluation.h); with the phonetic columns
// measured on a head (stimuli/articulation.h).
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/learn/evaluation.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/commands.h"
#include "command.h"
#include "head_options.h"
#include "one_of.h"
#include "synth_choices.h"

namespace avsi::cli {
namespace {

const bool registered_evaluate = register_command({
    "evaluate",
    "Score models against an articulatory corpus: RMSE % of range and Pearson rho (Table 2), plus a plot",
    [](CLI::App& sub) -> std::function<int()> {
        auto s = std::make_shared<learn::EvaluationSettings>();
        auto seed = std::make_shared<std::uint64_t>(0);
        auto fraction = std::make_shared<double>(0.0);
        sub.add_option("--corpus", s->corpus, "Corpus folder (corpus.json or corpus.csv)")->required();
        sub.add_option("--models", s->models, "Model files (.json), one or more")->required();
        sub.add_option("--out", s->out,
                       "Output prefix: writes <out>.csv, <out>.md, <out>.svg and <out>_phonetic.csv")->required();
        sub.add_option("--subset", s->subset, "Utterances to score: test, train or all")
            ->capture_default_str()
            ->check(one_of({"test", "train", "all"}));
        auto* seed_opt = sub.add_option("--split-seed", *seed, "Split seed (default: the corpus manifest's)");
        auto* fraction_opt =
            sub.add_option("--test-fraction", *fraction, "Test fraction (default: the corpus manifest's)");
        sub.add_option("--plot-utterance", s->plot_utterance, "Utterance id to plot (default: the first scored)");
        sub.add_option("--plot-param", s->plot_param, "Parameter to plot")
            ->capture_default_str()
            ->check(one_of(param_names()));
        auto head = std::make_shared<stimuli::HeadFiles>();
        auto phonetic = std::make_shared<bool>(true);
        add_head_options(sub, *head);
        sub.add_flag("!--no-phonetic", *phonetic,
                     "Leave out the phonetic columns (bilabial closure and labiodental contact measured on the head)");
        sub.add_flag("--closure-hold", s->closure_hold,
                     "Also score each model under the closure constraint (closure = \"hold\" in a protocol), as <name>+hold");
        return [s, seed, fraction, seed_opt, fraction_opt, head, phonetic] {
            if (seed_opt->count()) s->split_seed = *seed;
            if (fraction_opt->count()) s->test_fraction = *fraction;
            std::shared_ptr<const stimuli::Head> loaded;
            std::shared_ptr<const stimuli::ArticulationMeter> meter;
            if (*phonetic) {
                loaded = std::make_shared<const stimuli::Head>(stimuli::load_head_files(*head));
                meter = std::make_shared<const stimuli::ArticulationMeter>(*loaded);
                s->articulation = [meter, loaded](const synth::Trajectory& t) { return meter->measure(t); };
                s->lip_tasks = [meter, loaded](const synth::Frame& frame) {
                    stimuli::Pose pose;
                    pose.params = frame;
                    const auto m = meter->measure(pose);
                    return synth::LipTaskMeasures{m.aperture_max_mm, m.lip_to_incisors_mm};
                };
                s->articulation_head = !head->gltf.empty()                      ? head->gltf.filename().string()
                                       : head->rig == stimuli::default_head_rig() ? "the built-in head"
                                                                                  : head->rig.filename().string();
            }
            const learn::EvaluationResult r = learn::run_evaluation(*s);
            fmt::print("{}\n", r.markdown);
            return 0;
        };
    },
});

}  // namespace
}  // namespace avsi::cli
