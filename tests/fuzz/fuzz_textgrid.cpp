// libFuzzer harness: the Praat TextGrid reader (long and short formats, UTF-8/16) and the phones it yields.
#include "avsi/core/labels.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto path = avsi::fuzz::input_file("in.TextGrid", text);
        (void)avsi::read_textgrid(path);
        (void)avsi::read_phones(path);
    });
}
