// libFuzzer harness: the trajectory CSV reader (time_s and the 10 parameters).
#include "avsi/synth/trajectory.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::synth::read_trajectory_csv(avsi::fuzz::input_file("traj.csv", text));
    });
}
