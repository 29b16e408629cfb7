// libFuzzer harness: the EST track reader (ASCII and binary, as MOCHA-TIMIT ships EMA).
#include "avsi/learn/est_track.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::learn::read_est_track(avsi::fuzz::input_file("in.est", text));
    });
}
