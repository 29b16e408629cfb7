// libFuzzer harness: the sentence corpus reader (id, text, keywords with alternates, list).
#include "avsi/core/corpus.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::read_corpus(avsi::fuzz::input_file("corpus.csv", text));
    });
}
