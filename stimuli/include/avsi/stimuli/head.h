// The talking head: a triangle mesh with per-vertex colours and named face
// groups (loaded from OBJ through tinyobjloader), and a rig that defines each
// of the 10 articulatory parameters (synth/parameters.h) as weighted geometric
// transforms of vertex regions, in the manner of Parke's parametric face
// (Parke 1982; Beskow 1995 §2): jaw opening is a rotation about the condylar
// hinge axis, lip gestures are translations and scalings of lip regions, each
// with smooth falloff weights. The neutral geometry gives the MPEG-4 facial
// animation parameter units (ISO/IEC 14496-2 Annex C; Charisma paper §3).
//
// The rig file (JSON, "format": "avsi-rig"):
//   "landmarks"     neutral-face points for the FAPUs and the camera (Landmarks);
//   "transforms"    the weighted transforms, applied in order (RigTransform):
//                   {"channel": <parameter or "blink">, "rotate" | "translate" |
//                    "scale": …, "region": {"groups": […], "smooth": n,
//                    "falloff": [{"ellipsoid": …} | {"halfspace": …}]}};
//   "articulation"  vertex indices of the landmarks the articulation measures
//                   use (ArticulationLandmarks; articulation.h), needed by
//                   `avsi measure` and the stimulus builder's checks:
//                   {"upper_lip_contour": [i…], "lower_lip_contour": [i…],
//                    "mouth_corners": [left, right], "upper_lip_point": i,
//                    "lower_lip_point": i, "upper_incisor_edge": [i…],
//                    "lower_incisor_edge": [i…], "lower_lip_surface": [i…],
//                    "up": [x, y, z], "forward": [x, y, z]};
//   "lip_contact"   optional, needs "articulation": the lips flatten against
//                   each other instead of passing through (LipContact):
//                   {"upper": <region>, "lower": <region>, "reach_mm": d}.
//
// Usage:
//   auto head = avsi::stimuli::load_default_head();
//   avsi::stimuli::Pose pose;                  // rest
//   pose.params[index(Param::JawRotation)] = 0.8;
//   avsi::stimuli::PosedMesh posed;
//   avsi::stimuli::pose_head(head, pose, posed);
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "avsi/synth/parameters.h"
#include "avsi/synth/trajectory.h"

namespace avsi::stimuli {

// Mesh units are millimetres throughout the built-in head; a lab's own head
// may use any unit as long as its rig uses the same.
struct HeadMesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> colors;        // linear RGB in [0, 1]
    std::vector<std::uint32_t> indices;   // triangles, counter-clockwise from outside
    std::vector<std::string> group_names; // OBJ groups ("o"/"g" names)
    std::vector<int> triangle_group;      // per triangle, index into group_names

    std::size_t triangle_count() const { return indices.size() / 3; }
    // The index of a group by name, or -1.
    int group_index(const std::string& name) const;
};

enum class TransformKind { Rotate, Translate, Scale };

// One weighted transform of the rig, driven by one channel (a parameter name
// or "blink") at `amount` per unit of the channel.
struct RigTransform {
    std::string channel;
    TransformKind kind = TransformKind::Translate;
    glm::vec3 pivot{0.0f};     // Rotate and Scale: centre
    glm::vec3 axis{1, 0, 0};   // Rotate: unit axis
    float angle_deg = 0.0f;    // Rotate: degrees per unit
    glm::vec3 offset{0.0f};    // Translate: mesh units per unit
    glm::vec3 scale{0.0f};     // Scale: relative change per unit along x, y, z
    // Sparse weights in (0, 1]: vertex index and weight.
    std::vector<std::uint32_t> vertices;
    std::vector<float> weights;
    int channel_index = -1;    // resolved: parameter index, or param_count for blink
};

// Landmarks of the neutral head (mesh units), for the FAPUs and the camera.
struct Landmarks {
    glm::vec3 left_eye{0.0f};     // centre of the speaker's left eyeball
    glm::vec3 right_eye{0.0f};
    glm::vec3 nose_bottom{0.0f};  // subnasale
    glm::vec3 mouth_left{0.0f};   // speaker's left mouth corner
    glm::vec3 mouth_right{0.0f};
    glm::vec3 mouth_middle{0.0f}; // midpoint of the lip contact
    float iris_diameter = 0.0f;
    glm::vec3 head_center{0.0f};  // camera target
    float head_height = 0.0f;     // crown to chin, for framing
};

// MPEG-4 facial animation parameter units: the neutral-face distances in mesh
// units; one FAPU is the distance / 1024 (IRISD likewise).
struct Fapu {
    double mns = 0.0;    // mouth-nose separation
    double mw = 0.0;     // mouth width
    double ens = 0.0;    // eye-nose separation
    double es = 0.0;     // eye separation
    double irisd = 0.0;  // iris diameter
    double unit(double distance) const { return distance / 1024.0; }
};

// Landmark vertices for the articulation measures (articulation.h), from the
// rig's "articulation" section. Contours are paired point for point, from one
// mouth corner to the other (corners themselves excluded).
struct ArticulationLandmarks {
    std::vector<std::uint32_t> upper_lip_contour;  // inner edge of the upper lip
    std::vector<std::uint32_t> lower_lip_contour;  // inner edge of the lower lip, same count
    std::uint32_t mouth_corner_left = 0;            // the speaker's left corner
    std::uint32_t mouth_corner_right = 0;
    std::uint32_t upper_lip_point = 0;              // most forward midline point of the upper vermilion
    std::uint32_t lower_lip_point = 0;              // of the lower vermilion
    std::vector<std::uint32_t> upper_incisor_edge;  // along the upper incisors' cutting edge
    std::vector<std::uint32_t> lower_incisor_edge;
    std::vector<std::uint32_t> lower_lip_surface;   // lower-lip points that meet the upper incisors in /f v/
    glm::vec3 up{0.0f, 1.0f, 0.0f};                 // the head's up and forward axes (unit)
    glm::vec3 forward{0.0f, 0.0f, 1.0f};
};

// Lip contact (the rig's "lip_contact" section): after the transforms, where
// the lower lip's inner edge has passed above the upper lip's, the two lips
// are pushed apart to meet at the midpoint, each vertex of a lip region by
// its weight times half the overlap at its lateral position (interpolated
// between the contour pairs, zero at the corners). Weights are the region's
// times a falloff with the vertex's vertical distance from its lip's edge at
// rest (1 at the edge, 0 at reach_mm), so the lips flatten against each
// other as pressed lips do instead of passing through each other.
//
// The points the step reads and moves, as indices into a position array
// (mesh vertices for pose_head; landmark slots for the articulation meter).
struct LipContactPoints {
    std::vector<std::uint32_t> upper, lower;  // the contour pairs
    std::vector<std::uint32_t> moved;         // points moved
    std::vector<float> sign_weight;           // +weight upper lip (moves up), −weight lower lip
    std::vector<float> lateral;               // rest lateral position of each moved point
};
struct LipContact {
    std::vector<float> pair_lateral;     // rest lateral position of each contour pair, ascending
    std::vector<std::size_t> pair_order; // contour pair index for each pair_lateral entry
    float corner_lateral_min = 0.0f, corner_lateral_max = 0.0f;
    glm::vec3 up{0.0f, 1.0f, 0.0f};
    LipContactPoints mesh;               // over the head's vertices
};

// Applies the contact step to `positions` (see LipContact).
void apply_lip_contact(const LipContact& contact, const LipContactPoints& points, std::vector<glm::vec3>& positions);

// The names of the "articulation" section's fields, all required.
const std::vector<std::string>& articulation_landmark_names();

struct Head {
    HeadMesh mesh;
    std::vector<RigTransform> transforms;  // applied in order
    Landmarks landmarks;
    std::optional<ArticulationLandmarks> articulation;  // absent when the rig has no such section
    std::optional<LipContact> lip_contact;              // absent: no contact step (needs articulation)
    std::filesystem::path obj_path;
    std::filesystem::path rig_path;
};

// The channels a pose sets: the 10 parameters and the eyelid closure.
struct Pose {
    synth::Frame params{};   // normalised units, 0 = rest
    double blink = 0.0;      // 0 = eyes open, 1 = closed
};

struct PosedMesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> normals;  // smooth, area-weighted
};

// Loads an OBJ (with per-vertex colours "v x y z r g b") and a rig JSON; throws
// InputError naming the file and field on bad input.
Head load_head(const std::filesystem::path& obj_path, const std::filesystem::path& rig_path);
// The built-in head in protocols/head/.
Head load_default_head();
std::filesystem::path default_head_obj();
std::filesystem::path default_head_rig();

// The FAPUs measured on the neutral geometry.
Fapu fapu(const Head& head);

// Applies one rig transform at `amount` (units of its channel) to
// positions[targets[k]] with weights[k]: the arithmetic pose_head uses.
void apply_transform(const RigTransform& t, float amount, const std::vector<std::uint32_t>& targets,
                     const std::vector<float>& weights, std::vector<glm::vec3>& positions);

// The posed vertex positions (no normals).
void pose_positions(const Head& head, const Pose& pose, std::vector<glm::vec3>& positions);

// Deforms the neutral mesh by the rig for `pose` and recomputes smooth normals.
// `out` is reused between calls to avoid reallocation.
void pose_head(const Head& head, const Pose& pose, PosedMesh& out);

// Smooth vertex normals (area-weighted face normals) of a triangle mesh.
void compute_normals(const std::vector<glm::vec3>& positions,
                     const std::vector<std::uint32_t>& indices, std::vector<glm::vec3>& normals);

}  // namespace avsi::stimuli
