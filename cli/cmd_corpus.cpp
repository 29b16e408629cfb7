// `avsi corpus <action>`: articulatory corpora for training and evaluating
// control models. `avsi corpus reference --out DIR` writes the synthetic
// reference speaker's corpus (learn/reference_speaker.h). Each action is a
// sub-subcommand; importing recorded corpora is to come as another action.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/learn/articulatory_corpus.h"
#include "avsi/learn/reference_speaker.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct ReferenceOptions {
    std::string out;
    std::string sentences;
    bool voice_given = false;
    learn::ReferenceSpeakerSettings settings;
};

int run_reference(const ReferenceOptions& o) {
    learn::ReferenceSpeakerSettings s = o.settings;
    s.sentences_path = o.sentences;
    learn::resolve_reference_language(s, o.voice_given);
    const std::size_t n = learn::write_reference_corpus(o.out, s);
    const learn::ArticulatoryCorpus corpus = learn::load_articulatory_corpus(o.out);
    const learn::CorpusSplit split = learn::split_corpus(corpus);
    log_info("wrote {} utterances to {} ({} train / {} test, split seed {}); corpus hash {}", n, o.out,
             split.train_ids.size(), split.test_ids.size(), split.seed, corpus.hash);
    return 0;
}

void add_reference(CLI::App& corpus, std::function<int()>& chosen) {
    auto o = std::make_shared<ReferenceOptions>();
    CLI::App* sub = corpus.add_subcommand(
        "reference", "Write the synthetic reference speaker's corpus (critically damped articulator dynamics "
                     "over espeak-ng-timed sentences); deterministic for given options");
    sub->add_option("--out", o->out, "Output folder (corpus.json, tracks/, labels/)")->required();
    sub->add_option("--sentences", o->sentences, "Sentence list, one per line (default: the shipped list)")
        ->capture_default_str();
    sub->add_option("--seed", o->settings.seed, "Seed of the speaker's variation and noise")->capture_default_str();
    sub->add_option("--count", o->settings.max_utterances, "Use only the first N sentences (0: all)")
        ->capture_default_str();
    sub->add_option("--fps", o->settings.fps, "Frame rate of the parameter tracks")->capture_default_str();
    CLI::Option* voice = sub->add_option("--voice", o->settings.voice,
                                         "espeak-ng voice for the timing (default: the language's, en-us for en)")
                             ->capture_default_str();
    sub->add_option("--language", o->settings.language,
                    "The speaker's language: en, or sv (Swedish sentences and targets, espeak-ng sv timing)")
        ->capture_default_str();
    sub->add_option("--rate-min", o->settings.rate_min_wpm, "Slowest speaking rate (words per minute)")
        ->capture_default_str();
    sub->add_option("--rate-max", o->settings.rate_max_wpm, "Fastest speaking rate (words per minute)")
        ->capture_default_str();
    sub->add_option("--noise", o->settings.sensor_noise_sd, "Sensor noise sd, as a fraction of each range")
        ->capture_default_str();
    sub->add_option("--split-seed", o->settings.split_seed, "Seed of the train/test split in the manifest")
        ->capture_default_str();
    sub->add_option("--test-fraction", o->settings.test_fraction, "Fraction of utterances in the test split")
        ->capture_default_str();
    sub->callback([o, voice, &chosen] {
        o->voice_given = voice->count() > 0;
        chosen = [o] { return run_reference(*o); };
    });
}

const bool registered_corpus = register_command({
    "corpus",
    "Make articulatory corpora for training and evaluating control models; import and balance sentence corpora",
    [](CLI::App& sub) -> std::function<int()> {
        sub.require_subcommand(1);
        auto chosen = std::make_shared<std::function<int()>>();
        add_reference(sub, *chosen);
        add_actions("corpus", sub, *chosen);  // import, balance: cmd_corpus_import.cpp
        return [chosen] { return *chosen ? (*chosen)() : static_cast<int>(ExitUsage); };
    },
});

}  // namespace
}  // namespace avsi::cli
