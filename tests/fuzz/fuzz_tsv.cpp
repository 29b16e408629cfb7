// libFuzzer harness: the TSV label reader and the phones it yields.
#include "avsi/core/labels.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::read_phones(avsi::fuzz::input_file("in.tsv", text));
    });
}
