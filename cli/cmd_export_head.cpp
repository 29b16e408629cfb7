// `avsi export-head`: the built-in head (or any head) as glTF 2.0 with
// ARKit-named morph targets, for editing in Blender and bringing back with
// --head (docs/head-format.md).
#include <memory>

#include "avsi/stimuli/commands.h"
#include "command.h"
#include "head_options.h"

namespace avsi::cli {
namespace {

const bool registered_export_head = register_command({
    "export-head",
    "Write a head as glTF (.glb) with ARKit-named blendshapes and its articulation landmarks",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<stimuli::ExportHeadSettings>();
        sub.footer(
            "The morph targets are the ones the mapping names (protocols/head/arkit_mapping.json), each the head's "
            "rig posed at that end of its parameter's range; `avsi render --head OUT.glb` reads the file back.");
        sub.add_option("--out", o->out_path, "Output .glb (binary glTF) or .gltf")->required();
        add_head_options(sub, o->head);
        return [o] {
            stimuli::run_export_head(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
