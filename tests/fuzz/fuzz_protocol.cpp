// libFuzzer harness: the TOML protocol parser and validator.
#include "avsi/core/protocol.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::parse_protocol(text, "protocol.toml");
    });
}
