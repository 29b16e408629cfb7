// `avsi design`: the counterbalanced trial lists of every subject (lists.csv)
// and a balance report written beside it.
#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/analysis/adaptive.h"
#include "avsi/core/corpus.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/protocol.h"
#include "avsi/experiment/design.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct DesignOptions {
    std::string protocol;
    int subjects = 25;
    std::string out = "lists.csv";
};

int run_design(const DesignOptions& o) {
    const Protocol protocol = load_protocol(o.protocol);
    const Corpus corpus = read_corpus(protocol.corpus.sentences);
    // An adaptive track aimed above a condition's ceiling cannot converge: say so before the study runs.
    std::size_t keywords = 1;
    for (const auto& sentence : corpus.sentences) keywords = std::max(keywords, sentence.keywords.size());
    for (const auto& w : analysis::adaptive_design_warnings(analysis::adaptive_protocol(protocol), static_cast<int>(keywords)))
        log_warning("{}: {}", o.protocol, w);
    const auto trials = experiment::make_design(protocol, corpus, o.subjects);
    experiment::write_lists_csv(o.out, trials);
    const auto report = experiment::balance_report(protocol, trials);
    const std::filesystem::path out(o.out);
    const std::filesystem::path report_path = out.parent_path() / (out.stem().string() + "_balance.txt");
    write_text_file(report_path, report.text());
    fmt::print("{}\n", report.text());
    log_info("wrote {} ({} trials for {} subjects, counterbalance {}, seed {}) and {}", o.out, trials.size(),
             o.subjects, to_string(protocol.design.counterbalance), protocol.design.seed, report_path.string());
    return 0;
}

const bool registered_design = register_command({
    "design",
    "Counterbalanced trial lists per subject (lists.csv) with a balance report",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<DesignOptions>();
        sub.add_option("protocol", o->protocol, "Protocol file (TOML)")->required()->check(CLI::ExistingFile);
        sub.add_option("--subjects", o->subjects, "Number of subjects (a multiple of the number of conditions "
                                                  "balances lists against conditions)")
            ->capture_default_str()
            ->check(CLI::Range(1, 100000));
        sub.add_option("--out", o->out, "Output lists.csv; the balance report goes beside it (<stem>_balance.txt)")
            ->capture_default_str();
        return [o] { return run_design(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
