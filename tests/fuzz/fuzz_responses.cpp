// libFuzzer harness: a responses CSV scored against tests/data/experiment's
// sentence corpus (score_files: `avsi score`), outputs in the temp folder.
#include "avsi/analysis/scoring.h"
#include "fuzz_support.h"

namespace {

avsi::analysis::ScoreFilesSettings settings_for(const std::filesystem::path& responses) {
    avsi::analysis::ScoreFilesSettings s;
    s.corpus = std::filesystem::path(AVSI_TEST_DATA_DIR) / "experiment" / "corpus.csv";
    s.responses = responses;
    s.out_dir = responses.parent_path() / "scores";
    return s;
}

}  // namespace

// Scores the good responses once, so the shared lexicon (loaded and sorted on
// first use, seconds under the sanitizers) is not charged to the first input.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
    const auto good = std::filesystem::path(AVSI_TEST_DATA_DIR) / "malformed" / "_support" / "responses.csv";
    auto s = settings_for(good);
    s.out_dir = avsi::fuzz::input_file("warmup", "").parent_path() / "warmup_scores";
    (void)avsi::analysis::score_files(s);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::analysis::score_files(settings_for(avsi::fuzz::input_file("responses.csv", text)));
    });
}
