// `avsi corpus import` and `avsi corpus balance`: sentence corpora for the
// intelligibility test. `import` proposes keywords for an unmarked sentence
// list and reports what it did (core/keyword_proposals.h); `balance` assigns
// the test lists of a corpus, balanced for keyword frequency, syllables and
// keyword viseme content, and writes a Markdown report (core/list_balance.h).
// Both are actions of `avsi corpus` (cmd_corpus.cpp), added through
// register_action.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/analysis/alternates.h"
#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/keyword_proposals.h"
#include "avsi/core/list_balance.h"
#include "avsi/core/log.h"
#include "avsi/core/tts.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct ImportOptions {
    std::string input;
    std::string out;
    std::string report;
    bool no_alternates = false;
    ImportSettings settings;
};

int run_import(ImportOptions o) {
    const auto lines = read_sentence_lines(o.input);
    // Alternates come from the scoring module's tables; core's import takes them as a function.
    if (!o.no_alternates) o.settings.alternates = analysis::AlternateFinder::load_default()->proposer();
    ImportOutcome outcome = import_listed_sentences(lines, o.settings);
    outcome.corpus.path = o.out;
    write_corpus(o.out, outcome.corpus);
    if (o.report.empty()) fmt::print("{}", outcome.report);
    else write_text_file(o.report, outcome.report);
    log_info("wrote {} sentences to {}{}", outcome.corpus.sentences.size(), o.out,
             o.report.empty() ? "" : ", report to " + o.report);
    return 0;
}

void add_import(CLI::App& corpus, std::function<int()>& chosen) {
    auto o = std::make_shared<ImportOptions>();
    CLI::App* sub = corpus.add_subcommand(
        "import", "Propose keywords (content words; nouns, verbs and adjectives first, rarer first by word "
                  "frequency) and alternates to review for a sentence list and write a corpus CSV; reports the "
                  "choice per sentence");
    sub->add_option("sentences", o->input,
                    "Sentence list: one sentence a line (numbering such as '1.' or '(1)' and bullets removed), "
                    "'List N' headings set the list, '#' comments")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("--out", o->out, "Corpus CSV to write (id,text,keywords)")->required();
    sub->add_option("--report", o->report, "Write the report to this file instead of standard output")
        ->capture_default_str();
    sub->add_option("--keywords", o->settings.keywords, "Keywords per sentence")
        ->capture_default_str()
        ->check(CLI::Range(1, 20));
    sub->add_option("--min-syllables", o->settings.min_syllables,
                    "Report sentences with fewer syllables (0 with --max-syllables 0: do not count)")
        ->capture_default_str();
    sub->add_option("--max-syllables", o->settings.max_syllables, "Report sentences with more syllables")
        ->capture_default_str();
    sub->add_option("--voice", o->settings.voice, "espeak-ng voice for counting syllables")->capture_default_str();
    sub->add_option("--id-prefix", o->settings.id_prefix, "Prefix of the sentence ids")->capture_default_str();
    sub->add_flag("--no-alternates", o->no_alternates,
                  "Propose no alternates (default: inflections and spelling variants in the `review` column)");
    sub->callback([o, &chosen] { chosen = [o] { return run_import(*o); }; });
}

struct BalanceOptions {
    std::string input;
    std::string out;
    std::string report;
    BalanceSettings settings;
};

int run_balance(const BalanceOptions& o, const std::string& command_line) {
    const Corpus corpus = read_corpus(o.input);
    BalanceOutcome outcome = balance_corpus(corpus, o.settings);
    const std::string report =
        balance_report(corpus, outcome.profiles, outcome.assignment, o.settings, command_line);
    outcome.corpus.path = o.out;
    write_corpus(o.out, outcome.corpus);
    if (!o.report.empty()) write_text_file(o.report, report);
    else fmt::print("{}", report);
    log_info("balanced {} lists of {} (cost {:.3f}); wrote {}{}", o.settings.lists, o.settings.sentences_per_list,
             outcome.assignment.cost, o.out, o.report.empty() ? "" : " and " + o.report);
    return 0;
}

void add_balance(CLI::App& corpus, std::function<int()>& chosen) {
    auto o = std::make_shared<BalanceOptions>();
    CLI::App* sub = corpus.add_subcommand(
        "balance", "Assign a corpus's test lists balanced for keyword frequency, syllables and keyword viseme "
                   "content (seeded search); \"warmup\"/\"practice\" rows keep their mark, the other rows are "
                   "candidates");
    sub->add_option("corpus", o->input, "Corpus CSV (id,text,keywords[,list][,audio][,labels])")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("--out", o->out, "Corpus CSV to write with the list column assigned (may be the input)")
        ->required();
    sub->add_option("--report", o->report, "Markdown balance report (default: standard output)")
        ->capture_default_str();
    sub->add_option("--lists", o->settings.lists, "Test lists")->capture_default_str()->check(CLI::Range(1, 100));
    sub->add_option("--per-list", o->settings.sentences_per_list, "Sentences per test list")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    sub->add_option("--seed", o->settings.seed, "Seed of the search")->capture_default_str();
    sub->add_option("--restarts", o->settings.restarts, "Independent seeded starts")
        ->capture_default_str()
        ->check(CLI::Range(1, 10000));
    sub->add_option("--iterations", o->settings.iterations, "Swap proposals per start")
        ->capture_default_str()
        ->check(CLI::Range(0, 100000000));
    sub->add_option("--min-syllables", o->settings.min_syllables, "Syllable range: lower end (reported)")
        ->capture_default_str();
    sub->add_option("--max-syllables", o->settings.max_syllables, "Syllable range: upper end (reported)")
        ->capture_default_str();
    sub->add_option("--voice", o->settings.profile.voice,
                    "espeak-ng voice for syllables and keyword phones (sv, de, ...: no keyword frequency, whose "
                    "counts are English's)")
        ->capture_default_str();
    sub->callback([o, sub, &chosen] {
        // Keyword frequency is English's (SemCor): another language balances
        // syllables and visemes only.
        TtsSettings voice;
        voice.voice = o->settings.profile.voice;
        if (tts_voice_language(voice) != "en") {
            o->settings.profile.keyword_frequency = false;
            o->settings.frequency_weight = 0.0;
        }
        // The command line as the user would retype it, for the report.
        std::string line = fmt::format("avsi corpus balance {} --out {}", o->input, o->out);
        if (!o->report.empty()) line += " --report " + o->report;
        for (const auto* opt : {"--lists", "--per-list", "--seed", "--restarts", "--iterations", "--min-syllables",
                                "--max-syllables", "--voice"})
            if (sub->get_option(opt)->count() > 0) line += fmt::format(" {} {}", opt, sub->get_option(opt)->as<std::string>());
        chosen = [o, line] { return run_balance(*o, line); };
    });
}

const bool registered_import = register_action("corpus", add_import);
const bool registered_balance = register_action("corpus", add_balance);

}  // namespace
}  // namespace avsi::cli
