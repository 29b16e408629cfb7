// libFuzzer harness: a scores table (read_scores: `avsi analyze`'s input),
// then the within-subject data and the repeated-measures analysis on it.
#include "avsi/analysis/report.h"
#include "avsi/analysis/scores.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto scores = avsi::analysis::read_scores(avsi::fuzz::input_file("scores.csv", text));
        const auto within = avsi::analysis::make_within_data(scores);
        if (within.subjects.size() >= 2 && within.conditions.size() >= 2) (void)avsi::analysis::analyze(within);
    });
}
