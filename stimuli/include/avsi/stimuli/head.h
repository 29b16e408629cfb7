// The talking head: a triangle mesh with per-vertex colours, optional
// texture coordinates and named face groups (loaded from OBJ through
// tinyobjloader), and a rig that defines each of the 10 articulatory
// parameters (synth/parameters.h) as weighted transforms of the vertices:
// rotations, translations and scalings of weighted regions in the manner of
// Parke's parametric face (Parke 1982; Beskow 1995 §2), or baked per-vertex
// displacements ("blendshapes", as the built-in head's pose units give them;
// head_builder.h). The neutral geometry gives the MPEG-4 facial animation
// parameter units (ISO/IEC 14496-2 Annex C; Charisma paper §3).
//
// The rig file (JSON, "format": "avsi-rig"):
//   "texture"       optional: a PNG beside the rig file, sampled with the
//                   OBJ's texture coordinates (one per vertex) and multiplied
//                   by the vertex colours;
//   "materials"     optional, per group: {"specular": s, "shininess": n,
//                   "wrap": w (diffuse light wrapping round the terminator,
//                   0 = Lambert), "blend": true (alpha-blended, drawn after
//                   the opaque surfaces, back to front, both sides)}
//                   (Material; groups not named get defaults by their name);
//   "landmarks"     neutral-face points for the FAPUs and the camera (Landmarks);
//   "transforms"    the weighted transforms, applied in order (RigTransform):
//                   {"channel": <parameter, "blink", "tongue_tip", "gaze_left"
//                    or "gaze_up">,
//                    "side": "positive" | "negative" (optional: the transform
//                    acts only on that side of the channel's value),
//                    "rotate" | "translate" | "scale": …,
//                    "region": {"groups": […], "smooth": n,
//                    "falloff": [{"ellipsoid": …} | {"halfspace": …}]}
//                    or "weights": {"vertices": [i…], "values": [w…]}} or
//                   {"channel": …, "blendshape": {"vertices": [i…],
//                    "offsets": [dx, dy, dz, …]}} (mesh units per unit of the
//                   channel, optionally times a "region"'s weights);
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
#include <span>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "avsi/synth/parameters.h"
#include "avsi/synth/trajectory.h"

namespace avsi::stimuli {

// Mesh units are millimetres throughout the built-in head; a lab's own head
// may use any unit as long as its rig uses the same.
struct HeadMesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> colors;        // linear RGB in [0, 1]
    std::vector<glm::vec2> uvs;           // per vertex; empty when the head has no texture
    std::vector<std::uint32_t> indices;   // triangles, counter-clockwise from outside
    std::vector<std::string> group_names; // OBJ groups ("o"/"g" names)
    std::vector<int> triangle_group;      // per triangle, index into group_names

    std::size_t triangle_count() const { return indices.size() / 3; }
    // The index of a group by name, or -1.
    int group_index(const std::string& name) const;
};

// An 8-bit RGBA image, rows top to bottom (a head's texture).
struct ImageRgba {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgba;
};

// How a group's surface is shaded (the rig's "materials").
struct Material {
    float specular = 0.06f;   // strength of the soft highlight
    float shininess = 18.0f;  // Blinn-Phong exponent
    float wrap = 0.0f;        // diffuse wrap: light reaches (wrap) past the terminator, as in skin
    bool blend = false;       // alpha-blended (hair, brows, lashes): drawn after the opaque parts, two-sided
};

enum class TransformKind { Rotate, Translate, Scale, Blendshape };
// Which values of its channel a transform follows.
enum class ChannelSide { Both, Positive, Negative };

// The channels beyond the 10 parameters, in channel-index order after them.
inline constexpr std::size_t blink_channel = synth::param_count;
inline constexpr std::size_t tongue_tip_channel = synth::param_count + 1;
inline constexpr std::size_t gaze_left_channel = synth::param_count + 2;
inline constexpr std::size_t gaze_up_channel = synth::param_count + 3;
// The expression channels (animation layers, layers.h): the inner brows
// raised (negative: lowered and drawn together, a frown), the outer brows
// raised (negative: lowered), the cheeks raised. A head whose rig has no
// transforms for them loads and renders; the channels then move nothing.
inline constexpr std::size_t brow_inner_raise_channel = synth::param_count + 4;
inline constexpr std::size_t brow_outer_raise_channel = synth::param_count + 5;
inline constexpr std::size_t cheek_raise_channel = synth::param_count + 6;
inline constexpr std::size_t channel_count = synth::param_count + 7;
// Whether a channel moves the eyes and lids only (blink, gaze): the renderer
// caches those parts at rest.
inline constexpr bool is_eye_channel(std::size_t c) {
    return c == blink_channel || c == gaze_left_channel || c == gaze_up_channel;
}
// Whether a channel is an expression channel (brows, cheeks): at rest in
// speech-only stimuli, so the renderer caches what they move at rest.
inline constexpr bool is_expression_channel(std::size_t c) {
    return c == brow_inner_raise_channel || c == brow_outer_raise_channel || c == cheek_raise_channel;
}
// The rig names of the channels, in channel-index order: the 10 parameter
// names, then "blink", "tongue_tip", "gaze_left", "gaze_up",
// "brow_inner_raise", "brow_outer_raise", "cheek_raise".
const std::vector<std::string>& channel_names();

// One weighted transform of the rig, driven by one channel (a parameter name,
// "blink" or "tongue_tip") at `amount` per unit of the channel.
struct RigTransform {
    std::string channel;
    TransformKind kind = TransformKind::Translate;
    ChannelSide side = ChannelSide::Both;
    glm::vec3 pivot{0.0f};     // Rotate and Scale: centre
    glm::vec3 axis{1, 0, 0};   // Rotate: unit axis
    float angle_deg = 0.0f;    // Rotate: degrees per unit
    glm::vec3 offset{0.0f};    // Translate: mesh units per unit
    glm::vec3 scale{0.0f};     // Scale: relative change per unit along x, y, z
    // Sparse weights in (0, 1]: vertex index and weight.
    std::vector<std::uint32_t> vertices;
    std::vector<float> weights;
    std::vector<glm::vec3> offsets;  // Blendshape: per entry of `vertices`, mesh units per unit
    int channel_index = -1;    // resolved: parameter index or one of the *_channel constants
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
    // The pivot of head rotation (the top of the neck: the skull's joint on
    // the spine). From the rig's "neck_pivot" landmark; a rig without one
    // (has_neck_pivot false) gets the point 0.35 head heights behind the
    // eyes' midpoint, a quarter of the way up from the subnasale's height to
    // the eyes' (where the built-in head's pivot lies; y up, z forward).
    glm::vec3 neck_pivot{0.0f};
    bool has_neck_pivot = false;
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
// other as pressed lips do instead of passing through each other. The
// contour points themselves move by their own pair's half overlap (weight 1),
// so every measured pair meets exactly (contour points should be distinct).
//
// The points the step reads and moves, as indices into a position array
// (mesh vertices for pose_head; landmark slots for the articulation meter).
struct LipContactPoints {
    std::vector<std::uint32_t> upper, lower;  // the contour pairs
    std::vector<std::uint32_t> moved;         // points moved
    std::vector<float> sign_weight;           // +weight upper lip (moves up), −weight lower lip
    std::vector<float> lateral;               // rest lateral position of each moved point
    std::vector<int> pair;                    // the contour pair a moved contour point belongs to, or −1
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
    std::vector<Material> materials;  // per group of the mesh
    std::optional<ImageRgba> texture; // the rig's "texture" (needs mesh.uvs)
    std::vector<RigTransform> transforms;  // applied in order
    Landmarks landmarks;
    std::optional<ArticulationLandmarks> articulation;  // absent when the rig has no such section
    std::optional<LipContact> lip_contact;              // absent: no contact step (needs articulation)
    std::filesystem::path obj_path;
    std::filesystem::path rig_path;
    std::filesystem::path texture_path;  // empty without a texture
};

// The channels a pose sets: the 10 parameters, the eyelid closure, the
// tongue tip, the gaze, the expression channels, and the head's rotation.
struct Pose {
    synth::Frame params{};   // normalised units, 0 = rest
    double blink = 0.0;      // 0 = eyes open, 1 = closed
    double tongue_tip = 0.0; // 0 = at rest, 1 = raised to the teeth / alveolar ridge
    double gaze_left = 0.0;  // 0 = at the camera; 1 = the eyes turned to the speaker's left by their pose unit (about 19°), −1 right
    double gaze_up = 0.0;    // 0 = at the camera; 1 = up by the pose unit, −1 down
    double brow_inner_raise = 0.0;  // 1 = inner brows fully raised, −1 lowered and drawn together
    double brow_outer_raise = 0.0;  // 1 = outer brows fully raised, −1 lowered
    double cheek_raise = 0.0;       // 1 = cheeks fully raised (as in a smile), −1 the reverse
    // The head's rotation about the neck pivot (Landmarks::neck_pivot), a
    // rigid model transform applied after the rig (apply_head_rotation): the
    // articulation measures, in head coordinates, do not see it.
    glm::quat head_rotation{1.0f, 0.0f, 0.0f, 0.0f};
    // Whether the eyes and lids are at rest (no blink, no gaze).
    bool eyes_at_rest() const { return blink == 0.0 && gaze_left == 0.0 && gaze_up == 0.0; }
    // Whether the expression channels are at rest.
    bool expression_at_rest() const { return brow_inner_raise == 0.0 && brow_outer_raise == 0.0 && cheek_raise == 0.0; }
    // Whether the head is unrotated.
    bool head_at_rest() const { return head_rotation == glm::quat(1.0f, 0.0f, 0.0f, 0.0f); }
    // The value of channel c (an index below channel_count).
    double channel(std::size_t c) const;
    // Sets channel c.
    void set_channel(std::size_t c, double value);
};

// The value of a transform's channel in a pose, with its side applied (the
// amount pose_head moves the transform by).
double channel_amount(const RigTransform& t, const Pose& pose);

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
// positions[targets[j]] for the transform's entries entries[j] (indices into
// t.vertices, t.weights, t.offsets): the one arithmetic of the rig, used by
// pose_head (every entry onto its own vertex) and by the articulation meter
// (the landmark entries onto landmark slots).
void apply_transform(const RigTransform& t, float amount, std::span<const std::uint32_t> entries,
                     std::span<const std::uint32_t> targets, std::vector<glm::vec3>& positions);

// The posed vertex positions (no normals).
void pose_positions(const Head& head, const Pose& pose, std::vector<glm::vec3>& positions);

// Deforms the neutral mesh by the rig for `pose` and recomputes smooth normals.
// `out` is reused between calls to avoid reallocation.
void pose_head(const Head& head, const Pose& pose, PosedMesh& out);

// Turns a posed mesh rigidly by `rotation` about the head's neck pivot
// (positions and normals): the renderer's model transform for the head's
// rotation (Pose::head_rotation). The identity leaves `posed` untouched.
void apply_head_rotation(const Head& head, const glm::quat& rotation, PosedMesh& posed);

// Smooth vertex normals (area-weighted face normals) of a triangle mesh.
void compute_normals(const std::vector<glm::vec3>& positions,
                     const std::vector<std::uint32_t>& indices, std::vector<glm::vec3>& normals);

}  // namespace avsi::stimuli
