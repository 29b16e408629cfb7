// libFuzzer harness: the bounded JSON parser every JSON reader goes through.
#include "avsi/core/json.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::parse_json(text, "in.json");
    });
}
