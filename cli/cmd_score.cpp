// `avsi score`: keyword scoring of typed responses (keywords.csv, scores.csv).
#include <memory>
#include <string>

#include "avsi/analysis/scoring.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct ScoreOptions {
    std::string corpus, responses, out = "scores", overrides, homophones;
    bool strict = false;
};

const bool registered_score = register_command({
    "score",
    "Score typed responses against each sentence's keywords (keywords.csv, scores.csv)",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<ScoreOptions>();
        sub.add_option("--corpus", o->corpus, "Sentence corpus CSV (id,text,keywords with alternates)")
            ->required()
            ->check(CLI::ExistingFile);
        sub.add_option("--responses", o->responses,
                       "Responses CSV: subject,session,trial,phase,condition,list,sentence,response "
                       "(only phase = test is scored)")
            ->required()
            ->check(CLI::ExistingFile);
        sub.add_option("--out", o->out, "Output folder for keywords.csv, scores.csv (and overrides_applied.csv)")
            ->capture_default_str();
        sub.add_flag("--strict", o->strict, "No typo tolerance (Damerau-Levenshtein ≤ 1 for 5+ letter words)")
            ->capture_default_str();
        sub.add_option("--overrides", o->overrides,
                       "Manual overrides CSV: subject,trial or sentence,keyword_index,correct,reason")
            ->check(CLI::ExistingFile);
        sub.add_option("--homophones", o->homophones, "Homophone table (default: the shipped protocols/homophones.csv)")
            ->check(CLI::ExistingFile);
        return [o] {
            analysis::ScoreFilesSettings s;
            s.corpus = o->corpus;
            s.responses = o->responses;
            s.out_dir = o->out;
            s.overrides = o->overrides;
            s.scoring.strict = o->strict;
            s.scoring.homophones = o->homophones;
            analysis::score_files(s);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
