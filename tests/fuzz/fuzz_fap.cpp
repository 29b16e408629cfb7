// libFuzzer harness: the MPEG-4 FAP v2.1 stream reader and its conversion to a trajectory.
#include "avsi/synth/fap.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto stream = avsi::synth::read_fap(avsi::fuzz::input_file("in.fap", text));
        if (!stream.frames.empty()) (void)avsi::synth::fap_to_trajectory(stream);
    });
}
