// Readers of the MakeHuman asset formats the head tool builds the default
// head from (../shared/assets/makehuman/, CC0; head_builder.h), and the
// skeleton posing they imply:
//   - OBJ meshes with texture coordinates and groups (base mesh, proxies);
//   - .target shape targets: sparse per-vertex offsets;
//   - .mhclo proxy fitting: each proxy vertex a weighted sum of three base
//     vertices plus an offset scaled by the base mesh's measured size;
//   - .mhskel skeleton: bones with head/tail joints (means of base vertices)
//     and rotation planes giving each bone's rest frame;
//   - .mhw skinning weights;
//   - BVH face pose units (bone rotations per frame, named by the .json
//     frame mapping), Z-up files converted to the mesh's Y-up frame.
// Posing follows MakeHuman's conventions: a pose unit's rotations are given
// along the world axes and applied about each bone's head, cascading down
// the hierarchy; vertices follow by linear blend skinning.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace avsi::stimuli::detail {

// An OBJ mesh as MakeHuman writes them: polygons (3 or 4 corners) with a
// position and a texture coordinate index per corner, and a group per face.
struct MhMesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec2> uvs;
    struct Face {
        std::vector<std::uint32_t> v, vt;
        int group = 0;
    };
    std::vector<Face> faces;
    std::vector<std::string> group_names;
};

// Reads an OBJ (v, vt, g/o, f with v/vt corners); throws InputError with the line.
MhMesh read_mh_obj(const std::filesystem::path& path);

// A .target file: vertex index and offset (mesh units).
struct MhTarget {
    std::vector<std::uint32_t> vertices;
    std::vector<glm::vec3> offsets;
};
MhTarget read_target(const std::filesystem::path& path);
// Adds weight × the target's offsets to positions.
void apply_target(const MhTarget& target, float weight, std::vector<glm::vec3>& positions);

// A .mhclo proxy: its own mesh and how each of its vertices follows the base mesh.
struct MhProxy {
    std::string name;
    MhMesh mesh;
    std::filesystem::path material_texture;  // from the material's diffuseTexture, if the .mhmat is beside it
    std::vector<std::array<std::uint32_t, 3>> refs;
    std::vector<glm::vec3> ref_weights;
    std::vector<glm::vec3> offsets;
    // x/y/z_scale: the base vertices whose distance along that axis, divided
    // by the given length, scales the offsets.
    std::array<std::uint32_t, 3> scale_a{}, scale_b{};
    glm::vec3 scale_length{1.0f};
    int z_depth = 0;
};
MhProxy read_mhclo(const std::filesystem::path& path);
// The proxy's vertex positions fitted to base positions.
std::vector<glm::vec3> fit_proxy(const MhProxy& proxy, const std::vector<glm::vec3>& base);

// The skeleton (.mhskel) with its skinning weights (.mhw).
struct MhSkeleton {
    struct Bone {
        std::string name;
        int parent = -1;
        std::string head_joint, tail_joint, plane;
    };
    std::vector<Bone> bones;  // parents before children
    std::map<std::string, std::vector<std::uint32_t>> joints;
    std::map<std::string, std::array<std::string, 3>> planes;
    // Per bone, the vertices it weights and their weights.
    std::vector<std::vector<std::pair<std::uint32_t, float>>> weights;

    int bone_index(const std::string& name) const;
    // Whether bone b is `ancestor` or lies below it.
    bool descends_from(int b, int ancestor) const;
};
MhSkeleton read_skeleton(const std::filesystem::path& mhskel, const std::filesystem::path& mhw);

// The rest frames of the bones on a (shaped) base mesh: columns x, y (head →
// tail), z and the head position.
std::vector<glm::mat4> rest_frames(const MhSkeleton& skeleton, const std::vector<glm::vec3>& base);
// A joint's position: the mean of its vertices.
glm::vec3 joint_position(const MhSkeleton& skeleton, const std::string& joint, const std::vector<glm::vec3>& base);

// A pose: per bone, a rotation along the world axes (identity = rest).
using MhPose = std::map<std::string, glm::mat3>;

// Face pose units: the BVH's frames named by the .json's framemapping.
std::map<std::string, MhPose> read_pose_units(const std::filesystem::path& bvh, const std::filesystem::path& json);

// Per bone, the matrix that takes rest positions to posed ones.
std::vector<glm::mat4> skinning_matrices(const MhSkeleton& skeleton, const std::vector<glm::mat4>& rest,
                                         const MhPose& pose);
// Linear blend skinning of the base positions (vertices without weights stay).
std::vector<glm::vec3> skin(const MhSkeleton& skeleton, const std::vector<glm::mat4>& matrices,
                            const std::vector<glm::vec3>& base);

}  // namespace avsi::stimuli::detail
