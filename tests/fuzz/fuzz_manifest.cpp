// libFuzzer harness: a stimulus folder's manifest.json (read_stimulus_manifest,
// what `avsi run` and `avsi import-web` check before anything is shown).
#include "avsi/experiment/runner.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto path = avsi::fuzz::input_file("manifest.json", text);
        (void)avsi::experiment::read_stimulus_manifest(path.parent_path());
    });
}
