// `avsi contact-sheet`: one labelled PNG of the head at rest and at the
// targets of /p f θ s ʃ w u i ɑ/ (protocols/head/contact_sheet_targets.csv).
#include <memory>

#include "avsi/stimuli/commands.h"
#include "command.h"

namespace avsi::cli {
namespace {

const bool registered_contact_sheet = register_command({
    "contact-sheet",
    "Render the head at rest and at a set of articulatory targets into one labelled PNG",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<stimuli::ContactSheetJobSettings>();
        sub.add_option("--out", o->out_path, "Output PNG")->required();
        sub.add_option("--targets", o->targets_path, "Targets CSV (label, phone, parameters…)")
            ->capture_default_str();
        sub.add_option("--mesh", o->head.obj, "Head mesh (OBJ with vertex colours and texture coordinates)")->capture_default_str();
        sub.add_option("--rig", o->head.rig, "Head rig (JSON)")->capture_default_str();
        sub.add_option("--head", o->head.gltf, "A glTF head (.glb/.gltf) with ARKit-named morph targets, instead of --mesh/--rig")
            ->excludes(sub.get_option("--mesh"))
            ->excludes(sub.get_option("--rig"));
        sub.add_option("--mapping", o->head.mapping,
                       "Blendshape mapping of a --head glTF (default: protocols/head/arkit_mapping.json)");
        sub.add_option("--camera", o->camera, "Camera: front or three-quarter")->capture_default_str();
        sub.add_option("--tile-width", o->sheet.tile_width, "Tile width in pixels")->capture_default_str();
        sub.add_option("--tile-height", o->sheet.tile_height, "Tile height in pixels")->capture_default_str();
        sub.add_option("--columns", o->sheet.columns, "Tiles per row")->capture_default_str();
        return [o] {
            stimuli::run_contact_sheet(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
