// The rig document's reader, shared by the OBJ + rig JSON head (head.cpp)
// and the glTF head (gltf_head.cpp), whose rig is assembled from the file's
// extras and the blendshape mapping.
#pragma once

#include <cstddef>
#include <optional>

#include <nlohmann/json.hpp>

#include "avsi/stimuli/head.h"

namespace avsi::stimuli::detail {

// Reads the rig sections of `doc` (head.h: texture, materials, landmarks,
// articulation, lip_contact, transforms) onto `head`, whose mesh, obj_path
// and rig_path (named in messages; textures relative to it) are set. Throws
// InputError with every problem. `uv_conflict`: a vertex with two texture
// coordinates, refused when the rig names a texture.
void read_rig(Head& head, const nlohmann::json& doc, std::optional<std::size_t> uv_conflict, bool check_format);

}  // namespace avsi::stimuli::detail
