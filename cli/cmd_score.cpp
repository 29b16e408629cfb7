// `avsi score`: keyword scoring of typed responses (keywords.csv, scores.csv,
// audit.csv; agreement with a second scorer).
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/analysis/language.h"
#include "avsi/analysis/phoneme_scoring.h"
#include "avsi/analysis/scoring.h"
#include "avsi/core/error.h"
#include "avsi/core/protocol.h"
#include "command.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

struct ScoreOptions {
    std::string protocol, corpus, responses, out = "scores", overrides, homophones, rules, agreement, language;
    std::string tts, pronunciations;
    bool strict = false, phonemes = false;
};

const bool registered_score = register_command({
    "score",
    "Score typed responses against each sentence's keywords (keywords.csv, scores.csv, audit.csv)",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<ScoreOptions>();
        sub.add_option("--protocol", o->protocol,
                       "Protocol file: its [corpus] sentences and [scoring] rules and homophones are the defaults")
            ->check(CLI::ExistingFile);
        sub.add_option("--corpus", o->corpus,
                       "Sentence corpus CSV (id,text,keywords with alternates); required without --protocol")
            ->check(CLI::ExistingFile);
        sub.add_option("--responses", o->responses,
                       "Responses CSV: subject,session,trial,phase,condition,list,sentence,response "
                       "(only phase = test is scored)")
            ->required()
            ->check(CLI::ExistingFile);
        sub.add_option("--out", o->out,
                       "Output folder for keywords.csv, scores.csv, audit.csv (and overrides_applied.csv, "
                       "agreement.csv, disagreements.csv)")
            ->capture_default_str();
        sub.add_option("--rules", o->rules,
                       "Rule set: strict (exact word, alternates, number words, US/UK spellings, homophones), "
                       "loose (also inflections of the keyword's root), lenient (also non-word misspellings); "
                       "default: the protocol's [scoring] rules, else strict (docs/scoring.md)")
            ->check(one_of(analysis::rule_set_names()));
        sub.add_flag("--strict", o->strict, "Same as --rules strict");
        sub.add_option("--language", o->language,
                       "Language of the keywords and answers: en, sv (Swedish), de (German): its number words, "
                       "homophones, spellings, inflections (hunspell) and lexicon; default: the language of the "
                       "protocol's voice (espeak:sv -> sv; Festival voices are English), else en")
            ->check(one_of(analysis::scoring_language_codes()));
        sub.add_option("--overrides", o->overrides,
                       "Manual overrides CSV: subject,trial or sentence,keyword_index,correct,reason "
                       "(audit.csv with `correct` edited and a reason is one)")
            ->check(CLI::ExistingFile);
        sub.add_option("--agreement", o->agreement,
                       "A second scorer's judgments (same layout: subject,trial or sentence,keyword_index,correct): "
                       "percent agreement and Cohen's kappa per rule set, disagreements listed")
            ->check(CLI::ExistingFile);
        sub.add_option("--homophones", o->homophones,
                       "Homophone table (default: the protocol's, else protocols/homophones.csv, General American; "
                       "protocols/homophones-rp.csv for RP)")
            ->check(CLI::ExistingFile);
        sub.add_flag("--phonemes", o->phonemes,
                     "Also score every phone: target sentence and answer transcribed with the protocol's front end "
                     "(letter-to-sound words marked), words then phones aligned by feature-weighted edit distance; "
                     "writes phonemes.csv and phoneme_alignment.csv (docs/phoneme-analysis.md)");
        sub.add_option("--tts", o->tts,
                       "Front end for --phonemes, festival:<voice> or espeak:<voice> (default: the protocol's "
                       "[corpus] tts, or espeak-ng's voice of the scoring language when that voice speaks another)");
        sub.add_option("--pronunciations", o->pronunciations,
                       "Pronunciation table for --phonemes (word<TAB>phones, e.g. \"garden\tG AA1 R D AH0 N\"); "
                       "its words take precedence over the front end")
            ->check(CLI::ExistingFile);
        return [o] {
            analysis::ScoreFilesSettings s;
            analysis::PhonemeFilesSettings p;
            std::string rules = "strict";
            if (!o->protocol.empty()) {
                const Protocol protocol = load_protocol(o->protocol);
                s.corpus = protocol.corpus.sentences;
                s.scoring = analysis::scoring_settings(protocol);
                rules = protocol.scoring.rules;
                p.tts.engine = protocol.corpus.tts_engine;
                p.tts.voice = protocol.corpus.tts_voice;
                p.recorded_targets = protocol.corpus.audio == CorpusAudio::Recordings;
            }
            if (!o->phonemes && (!o->tts.empty() || !o->pronunciations.empty()))
                throw UsageError("--tts and --pronunciations apply to --phonemes; add --phonemes");
            if (!o->tts.empty()) set_tts_voice(p.tts, o->tts, "--tts");
            if (!o->corpus.empty()) s.corpus = o->corpus;
            if (s.corpus.empty()) throw UsageError("--corpus (or --protocol, whose [corpus] sentences it uses) is required");
            if (o->strict && !o->rules.empty() && o->rules != "strict")
                throw UsageError(fmt::format("--strict and --rules {} disagree; give one", o->rules));
            if (o->strict) rules = "strict";
            if (!o->rules.empty()) rules = o->rules;
            const auto set = analysis::parse_rule_set(rules);
            if (!set) {
                const std::string hint = closest_match(rules, analysis::rule_set_names());
                throw UsageError(fmt::format("--rules: expected strict, loose or lenient, got \"{}\"{}", rules,
                                             hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
            }
            s.scoring.rules = *set;
            s.responses = o->responses;
            s.out_dir = o->out;
            s.overrides = o->overrides;
            s.agreement = o->agreement;
            if (!o->homophones.empty()) s.scoring.homophones = o->homophones;
            if (!o->language.empty()) s.scoring.language = o->language;
            analysis::score_files(s);
            if (o->phonemes) {
                // The front end speaks the scoring language: without --tts, a
                // voice of another language (recordings with language = "sv"
                // and no tts; --language sv) gives way to espeak-ng's voice of it.
                const std::string spoken = tts_voice_language(p.tts);
                if (spoken != s.scoring.language) {
                    if (!o->tts.empty())
                        throw UsageError(fmt::format(
                            "--tts {} speaks {}, but the answers are scored as \"{}\"; give a voice of \"{}\"{}", o->tts,
                            spoken.empty() ? "no language with a phone table" : "\"" + spoken + "\"",
                            s.scoring.language, s.scoring.language, spoken.empty() ? "" : " or --language " + spoken));
                    p.tts.engine = TtsEngine::Espeak;
                    p.tts.voice = s.scoring.language;
                }
                p.language = s.scoring.language;
                p.corpus = s.corpus;
                p.responses = s.responses;
                p.out_dir = s.out_dir;
                p.pronunciations = o->pronunciations;
                analysis::score_phoneme_files(p);
            }
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
