// libFuzzer harness: the glTF head reader (load_gltf_head), binary (.glb,
// when the input starts with the glTF magic) or JSON (.gltf), with the small
// mapping tests/data/fuzz/gltf/mapping.json (one target, jawOpen).
#include "avsi/stimuli/gltf_head.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto mapping = std::filesystem::path(AVSI_TEST_DATA_DIR) / "fuzz" / "gltf" / "mapping.json";
        const bool binary = text.substr(0, 4) == "glTF";
        const auto head = avsi::stimuli::load_gltf_head(avsi::fuzz::input_file(binary ? "in.glb" : "in.gltf", text), mapping);
        avsi::stimuli::PosedMesh posed;
        avsi::stimuli::Pose pose;
        for (auto& p : pose.params) p = 0.7;
        avsi::stimuli::pose_head(head, pose, posed);
    });
}
