// Bring your own head: a glTF 2.0 head (.glb or .gltf, read and written
// through tinygltf) whose morph targets carry ARKit blendshape names (jawOpen,
// mouthPucker, mouthRollLower, eyeBlink_L …, the convention avatar and
// face-capture tools export), driven by the same control models through an
// editable mapping from the 10 articulatory parameters to blendshape
// weights (protocols/head/arkit_mapping.json; docs/head-format.md).
//
// The mapping (JSON, "format": "avsi-blendshape-mapping"): "parameters"
// has one row per channel (the 10 parameters, "blink", optionally
// "tongue_tip"); a row is either {"<target>": w, …} — target weight = w ×
// the channel's value on both sides of rest — or {"positive": {…},
// "negative": {…}} — each side's targets reach weight w at that end of the
// parameter's range (synth/parameters.h) and 0 at rest. A head that lacks
// any target the mapping names is refused with the list of what is missing.
//
// The articulation landmarks and the rest of the rig come with the file:
// the glTF asset's extras hold {"avsi": {"landmarks": …, "articulation": …,
// "lip_contact": …, "materials": …}} as in the rig JSON (head.h), points in
// the glTF's units (metres) in the scene's frame, vertex indices counted
// over the mesh primitives in file order (node order, then primitive order;
// primitives of a node sharing one POSITION accessor share its vertices).
// Groups are the primitives' material names. The head is converted to
// millimetres on loading.
//
//   Head head = load_gltf_head("lab-head.glb");             // default mapping
//   export_gltf_head(load_default_head(), "avsi-head.glb");  // the built-in head, editable in Blender
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "avsi/stimuli/head.h"

namespace avsi::stimuli {

// One channel's row of the mapping: target → weight, per side.
struct MappingRow {
    std::map<std::string, float> both;      // weight per unit of the channel's value
    std::map<std::string, float> positive;  // weight at the channel's maximum
    std::map<std::string, float> negative;  // weight at the channel's minimum
};

struct BlendshapeMapping {
    std::filesystem::path path;
    std::map<std::string, MappingRow> rows;  // by channel name
    // Every target name the mapping uses, sorted.
    std::vector<std::string> targets() const;
};

// protocols/head/arkit_mapping.json.
std::filesystem::path default_blendshape_mapping();
// Reads a mapping; throws InputError naming the file and field.
BlendshapeMapping read_blendshape_mapping(const std::filesystem::path& path);

// Loads a glTF head (units converted to mm). Throws InputError naming the
// file: unreadable glTF, no mesh, missing morph targets (all listed), bad
// avsi extras.
Head load_gltf_head(const std::filesystem::path& path,
                    const std::filesystem::path& mapping_path = default_blendshape_mapping());

// Writes `head` as a binary glTF (.glb): one primitive per group with
// positions (metres), normals, texture coordinates, vertex colours, its
// texture, the morph targets the mapping names (each the head's rig posed
// at that side's end of the range, rotations taken as their displacement;
// a _L/_R pair splits the shape at the midline) and the avsi extras, so
// load_gltf_head reads it back. Throws InputError when the mapping gives a
// target to two channels.
void export_gltf_head(const Head& head, const std::filesystem::path& out_path,
                      const std::filesystem::path& mapping_path = default_blendshape_mapping());

}  // namespace avsi::stimuli
