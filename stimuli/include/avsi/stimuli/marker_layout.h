// Where motion-capture markers sit on a head: the marker layout file, and the
// head's rig seen at those markers (synth/marker_model.h) for the marker fit
// (learn/marker_fit.h; Beskow 2004 §3.3–3.5). The built-in head's layout,
// after the study's 30 face markers and 5 on a spectacle frame, is
// protocols/head/markers.json; docs/articulography.md shows how to write one
// for another head (a glTF head included).
//
// Layout (JSON, "format": "avsi-marker-layout", "version": 1):
//   "markers": [ {"name": "<label in the recording>", <where>, options}, … ]
// where a face marker is placed by one of
//   "vertex": i                   a mesh vertex (tied to the first triangle
//                                 that has it: eq. 2's v1 = i);
//   "triangle": [a, b, c], "weights": [wa, wb, wc]
//                                 a surface point of a triangle (weights
//                                 summing to 1; default the centroid);
//   "near": [x, y, z]             the vertex nearest to a point of the head's
//                                 frame in mm (y up, z forward, the speaker's
//                                 left +x), optionally among "groups": […]
//                                 (the mesh's group names) — a layout that
//                                 carries over between heads of one frame;
// and options "orientation": true (a strategic point of the orientation fit,
// §3.4: mouth corners, nose tip, chin, brows). A reference marker is
// {"name": …, "reference": true, "point": [x, y, z]}: a point rigid with the
// skull (the spectacle frame), in the head's frame in mm.
// Vertex indices of a glTF head are counted as load_gltf_head counts them
// (gltf_head.h). Every problem is reported with the file and the marker.
#pragma once

#include <filesystem>

#include "avsi/stimuli/head.h"
#include "avsi/synth/marker_model.h"

namespace avsi::stimuli {

// protocols/head/markers.json: the built-in head's layout.
std::filesystem::path default_marker_layout();

// Reads a layout and ties it to `head`: the model the marker fit takes. Its
// pose function poses only the marker triangles' vertices with the head's rig
// (the lip contact step is not applied), so it costs microseconds.
synth::MarkerModel load_marker_model(const Head& head, const std::filesystem::path& layout_path);

}  // namespace avsi::stimuli
