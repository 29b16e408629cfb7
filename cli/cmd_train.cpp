// `avsi train`: fits a control model (Cohen-Massaro, Öhman, MPEG-4 CM) to an
// articulatory corpus (learn/training.h) and writes the model file.
#include <memory>
#include <string>

#include "avsi/learn/ann_training.h"
#include "avsi/learn/training.h"
#include "command.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

const bool registered_train = register_command({
    "train",
    "Train a control model on an articulatory corpus (Levenberg-Marquardt, early stopping on the test split)",
    [](CLI::App& sub) -> std::function<int()> {
        auto s = std::make_shared<learn::TrainCommandSettings>();
        auto seed = std::make_shared<std::uint64_t>(0);
        auto fraction = std::make_shared<double>(0.0);
        sub.add_option("--model", s->training.model,
                       "Model kind: cohen-massaro, ohman, mpeg4-cohen-massaro (or mpeg4-cm), ann (= ann1), ann1 or ann2")
            ->capture_default_str()
            ->check(one_of({"cohen-massaro", "ohman", "mpeg4-cohen-massaro", "mpeg4-cm", "ann", "ann1", "ann2"}));
        sub.add_option("--corpus", s->corpus, "Corpus folder (corpus.json or corpus.csv)")->required();
        sub.add_option("--out", s->out, "Model file to write (.json)")->required();
        sub.add_option("--init", s->training.init_model,
                       "Model file to start from (default: protocols/models/<kind>.json)");
        auto* seed_opt = sub.add_option("--split-seed", *seed, "Split seed (default: the corpus manifest's)");
        auto* fraction_opt =
            sub.add_option("--test-fraction", *fraction, "Test fraction (default: the corpus manifest's)");
        sub.add_option("--max-iterations", s->training.max_iterations, "Iterations per stage at most")
            ->capture_default_str();
        sub.add_option("--patience", s->training.patience,
                       "Stop after this many iterations without a lower held-out error")
            ->capture_default_str();
        sub.add_option("--threads", s->training.threads, "Worker threads (0: all cores)")->capture_default_str();
        sub.add_option("--min-rate", s->training.min_rate_per_s,
                       "Cohen-Massaro, MPEG-4 CM: lower bound on the dominance rates theta, phi (s^-c)")
            ->capture_default_str();
        sub.add_option("--min-c", s->training.min_c,
                       "Cohen-Massaro: lower bound on the dominance exponent c (per phone)")
            ->capture_default_str();
        sub.add_option("--max-c", s->training.max_c,
                       "Cohen-Massaro: upper bound on c; equal to --min-c fixes c (one training stage)")
            ->capture_default_str();
        // ANN models (--model ann | ann1 | ann2; synth/ann_training.h).
        auto ann = std::make_shared<learn::AnnCommandSettings>();
        auto ann_ahead = std::make_shared<int>(0), ann_back = std::make_shared<int>(0);
        auto* ahead_opt = sub.add_option("--look-ahead", *ann_ahead, "ANN: frames of look-ahead (default: preset)");
        auto* back_opt = sub.add_option("--look-back", *ann_back, "ANN: frames of look-back (default: preset)");
        sub.add_option("--sweep-lookahead", ann->sweep,
                       "ANN: train the occlusion network for look-aheads FIRST..LAST (window 31); --out is a folder")
            ->capture_default_str();
        sub.add_option("--epochs", ann->training.max_epochs, "ANN: epochs at most")->capture_default_str();
        sub.add_option("--seed", ann->training.seed, "ANN: training seed")->capture_default_str();
        sub.add_option("--max-seconds", ann->training.max_seconds, "ANN: time budget per network (0: none)")
            ->capture_default_str();
        sub.add_option("--chunk-frames", ann->training.chunk_frames,
                       "ANN: truncated-BPTT chunk length in frames (0: whole utterances)")
            ->capture_default_str();
        auto* patience_opt = sub.get_option("--patience");
        return [s, seed, fraction, seed_opt, fraction_opt, ann, ann_ahead, ann_back, ahead_opt, back_opt,
                patience_opt] {
            if (seed_opt->count()) s->split.seed = *seed;
            if (fraction_opt->count()) s->split.test_fraction = *fraction;
            if (s->training.model.rfind("ann", 0) == 0) {
                ann->model = s->training.model;
                ann->corpus = s->corpus;
                ann->out = s->out;
                ann->split_seed = s->split.seed;
                ann->test_fraction = s->split.test_fraction;
                if (patience_opt->count()) ann->training.patience = s->training.patience;
                if (ahead_opt->count()) ann->look_ahead = *ann_ahead;
                if (back_opt->count()) ann->look_back = *ann_back;
                learn::run_ann_command(*ann);
                return 0;
            }
            learn::run_training(*s);
            return 0;
        };
    },
});

}  // namespace
}  // namespace avsi::cli
