// `avsi contact-sheet`: one labelled PNG of the head at rest and at the
// targets of /p f θ s ʃ w u i ɑ/ (protocols/head/contact_sheet_targets.csv).
#include <memory>

#include "avsi/stimuli/commands.h"
#include "command.h"
#include "head_options.h"
#include "one_of.h"

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
        add_head_options(sub, o->head);
        sub.add_option("--camera", o->camera, "Camera: front or three-quarter")
            ->capture_default_str()
            ->check(one_of({"front", "three-quarter"}));
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
