// libFuzzer harness: the head rig JSON (load_head: every rig section, on a
// tiny OBJ from tests/data/fuzz/head), then the head posed with every channel.
#include "avsi/stimuli/head.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto obj = std::filesystem::path(AVSI_TEST_DATA_DIR) / "fuzz" / "head" / "tiny.obj";
        const auto head = avsi::stimuli::load_head(obj, avsi::fuzz::input_file("in.rig.json", text));
        avsi::stimuli::Pose pose;
        for (auto& p : pose.params) p = 0.7;
        pose.blink = 1.0;
        pose.tongue_tip = 0.5;
        pose.gaze_left = -0.5;
        pose.gaze_up = 0.5;
        avsi::stimuli::PosedMesh posed;
        avsi::stimuli::pose_head(head, pose, posed);
        (void)avsi::stimuli::fapu(head);
    });
}
