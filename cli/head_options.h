// The head options of every command that draws or measures a head (`avsi
// render`, `contact-sheet`, `measure`, `export-head`, `evaluate`): the
// built-in head by default, a lab's OBJ mesh and rig, or a glTF head with
// ARKit-named morph targets (docs/head-format.md). Declared once here so the
// commands take the same options with the same texts. Header-only, for
// commands whose helper links avsi_stimuli.
#pragma once

#include <CLI/CLI.hpp>

#include "avsi/stimuli/commands.h"

namespace avsi::cli {

// Adds --mesh, --rig, --head (excluding the first two) and --mapping to
// `sub`, parsed into `head` (which must outlive the parse).
inline void add_head_options(CLI::App& sub, stimuli::HeadFiles& head) {
    CLI::Option* mesh =
        sub.add_option("--mesh", head.obj, "Head mesh (OBJ with vertex colours and texture coordinates)")
            ->capture_default_str();
    CLI::Option* rig =
        sub.add_option("--rig", head.rig, "Head rig (JSON; measuring needs its \"articulation\" landmarks)")
            ->capture_default_str();
    sub.add_option("--head", head.gltf, "A glTF head (.glb/.gltf) with ARKit-named morph targets, instead of --mesh/--rig")
        ->excludes(mesh)
        ->excludes(rig);
    sub.add_option("--mapping", head.mapping,
                   "Blendshape mapping between ARKit names and the articulatory parameters (default: "
                   "protocols/head/arkit_mapping.json)");
}

}  // namespace avsi::cli
