// libFuzzer harness: the head OBJ reader (load_head with a rig of landmarks
// only, tests/data/fuzz/head/landmarks_only.rig.json), then the head posed.
#include "avsi/stimuli/head.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto rig = std::filesystem::path(AVSI_TEST_DATA_DIR) / "fuzz" / "head" / "landmarks_only.rig.json";
        const auto head = avsi::stimuli::load_head(avsi::fuzz::input_file("in.obj", text), rig);
        avsi::stimuli::PosedMesh posed;
        avsi::stimuli::pose_head(head, avsi::stimuli::Pose{}, posed);
    });
}
