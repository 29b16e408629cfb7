// libFuzzer harness: a responses CSV scored against tests/data/experiment's
// sentence corpus (score_files: `avsi score`), outputs in the temp folder.
#include "avsi/analysis/scoring.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        avsi::analysis::ScoreFilesSettings s;
        s.corpus = std::filesystem::path(AVSI_TEST_DATA_DIR) / "experiment" / "corpus.csv";
        s.responses = avsi::fuzz::input_file("responses.csv", text);
        s.out_dir = s.responses.parent_path() / "scores";
        (void)avsi::analysis::score_files(s);
    });
}
