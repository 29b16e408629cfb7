// Readers of the MakeHuman asset formats and skeleton posing (makehuman.h).
#include "makehuman.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"

namespace avsi::stimuli::detail {

namespace {

using nlohmann::json;

std::vector<std::string> split_words(const std::string& line) {
    std::vector<std::string> out;
    std::istringstream in(line);
    for (std::string w; in >> w;) out.push_back(w);
    return out;
}

// A number of a line, or InputError naming file, line and field.
float number(const std::string& word, const std::filesystem::path& path, int line, const std::string& field) {
    float v = 0.0f;
    const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), v);
    if (ec != std::errc() || end != word.data() + word.size() || !std::isfinite(v))
        throw InputError(path.string(), line, 1, field, "expected a number, got \"" + word + "\"");
    return v;
}

std::uint32_t index(const std::string& word, std::size_t limit, const std::filesystem::path& path, int line,
                    const std::string& field) {
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), v);
    if (ec != std::errc() || end != word.data() + word.size() || v >= limit)
        throw InputError(path.string(), line, 1, field,
                         "expected an index in [0, " + std::to_string(limit) + "), got \"" + word + "\"");
    return static_cast<std::uint32_t>(v);
}

json read_json(const std::filesystem::path& path) {
    try {
        return json::parse(read_text_file(path));
    } catch (const json::parse_error& e) {
        throw InputError(path, std::string("not valid JSON: ") + e.what());
    }
}

}  // namespace

MhMesh read_mh_obj(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "cannot open: no such file");
    MhMesh mesh;
    int group = -1;
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty() || line[0] == '#') continue;
        const auto w = split_words(line);
        if (w.empty()) continue;
        if (w[0] == "v") {
            if (w.size() < 4) throw InputError(path.string(), n, 1, "v", "expected 3 coordinates");
            mesh.positions.push_back({number(w[1], path, n, "v"), number(w[2], path, n, "v"), number(w[3], path, n, "v")});
        } else if (w[0] == "vt") {
            if (w.size() < 3) throw InputError(path.string(), n, 1, "vt", "expected 2 coordinates");
            mesh.uvs.push_back({number(w[1], path, n, "vt"), number(w[2], path, n, "vt")});
        } else if (w[0] == "g" || w[0] == "o") {
            const std::string name = w.size() > 1 ? w[1] : "default";
            const auto it = std::find(mesh.group_names.begin(), mesh.group_names.end(), name);
            group = static_cast<int>(it - mesh.group_names.begin());
            if (it == mesh.group_names.end()) mesh.group_names.push_back(name);
        } else if (w[0] == "f") {
            if (w.size() < 4) throw InputError(path.string(), n, 1, "f", "expected at least 3 corners");
            if (group < 0) {
                group = static_cast<int>(mesh.group_names.size());
                mesh.group_names.push_back("default");
            }
            MhMesh::Face face;
            face.group = group;
            for (std::size_t k = 1; k < w.size(); ++k) {
                const auto slash = w[k].find('/');
                face.v.push_back(index(w[k].substr(0, slash), mesh.positions.size() + 1, path, n, "f") - 1);
                if (slash != std::string::npos) {
                    const auto rest = w[k].substr(slash + 1);
                    const auto vt = rest.substr(0, rest.find('/'));
                    if (!vt.empty()) face.vt.push_back(index(vt, mesh.uvs.size() + 1, path, n, "f") - 1);
                }
            }
            if (!face.vt.empty() && face.vt.size() != face.v.size())
                throw InputError(path.string(), n, 1, "f", "expected a texture coordinate on every corner or none");
            for (auto v : face.v)
                if (v == std::uint32_t(-1)) throw InputError(path.string(), n, 1, "f", "vertex index 0");
            mesh.faces.push_back(std::move(face));
        }
    }
    if (mesh.positions.empty()) throw InputError(path, "the mesh has no vertices");
    return mesh;
}

MhTarget read_target(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "cannot open: no such file");
    MhTarget t;
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty() || line[0] == '#') continue;
        const auto w = split_words(line);
        if (w.empty()) continue;
        if (w.size() != 4) throw InputError(path.string(), n, 1, "offset", "expected \"index dx dy dz\"");
        t.vertices.push_back(index(w[0], 1u << 24, path, n, "index"));
        t.offsets.push_back({number(w[1], path, n, "dx"), number(w[2], path, n, "dy"), number(w[3], path, n, "dz")});
    }
    return t;
}

void apply_target(const MhTarget& target, float weight, std::vector<glm::vec3>& positions) {
    for (std::size_t k = 0; k < target.vertices.size(); ++k) {
        if (target.vertices[k] >= positions.size())
            throw InputError("target", 0, 0, "index", "vertex " + std::to_string(target.vertices[k]) + " beyond the mesh");
        positions[target.vertices[k]] += weight * target.offsets[k];
    }
}

MhProxy read_mhclo(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "cannot open: no such file");
    MhProxy p;
    p.name = path.stem().string();
    std::filesystem::path obj, material;
    bool in_verts = false;
    std::string line;
    constexpr std::size_t limit = 1u << 24;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty() || line[0] == '#') continue;
        const auto w = split_words(line);
        if (w.empty()) continue;
        const bool numeric = std::isdigit(static_cast<unsigned char>(w[0][0])) != 0;
        if (in_verts && numeric) {
            if (w.size() == 1) {
                const auto v = index(w[0], limit, path, n, "verts");
                p.refs.push_back({v, v, v});
                p.ref_weights.push_back({1.0f, 0.0f, 0.0f});
                p.offsets.push_back(glm::vec3(0.0f));
            } else if (w.size() == 9) {
                p.refs.push_back({index(w[0], limit, path, n, "verts"), index(w[1], limit, path, n, "verts"),
                                  index(w[2], limit, path, n, "verts")});
                p.ref_weights.push_back(
                    {number(w[3], path, n, "verts"), number(w[4], path, n, "verts"), number(w[5], path, n, "verts")});
                p.offsets.push_back(
                    {number(w[6], path, n, "verts"), number(w[7], path, n, "verts"), number(w[8], path, n, "verts")});
            } else {
                throw InputError(path.string(), n, 1, "verts", "expected 1 or 9 numbers, got " + std::to_string(w.size()));
            }
            continue;
        }
        // Keyword lines (tags among the vertex lines) do not end the vertex
        // section; another section does.
        if (w[0] == "verts") in_verts = true;
        else if (w[0] == "delete_verts" || w[0] == "weights") in_verts = false;
        else if (w[0] == "obj_file" && w.size() > 1) obj = path.parent_path() / w[1];
        else if (w[0] == "material" && w.size() > 1) material = path.parent_path() / w[1];
        else if (w[0] == "z_depth" && w.size() > 1) p.z_depth = static_cast<int>(number(w[1], path, n, "z_depth"));
        else if ((w[0] == "x_scale" || w[0] == "y_scale" || w[0] == "z_scale") && w.size() == 4) {
            const int axis = w[0][0] - 'x';
            p.scale_a[axis] = index(w[1], limit, path, n, w[0]);
            p.scale_b[axis] = index(w[2], limit, path, n, w[0]);
            p.scale_length[axis] = number(w[3], path, n, w[0]);
            if (!(p.scale_length[axis] > 0.0f)) throw InputError(path.string(), n, 1, w[0], "expected a positive length");
        }
    }
    if (obj.empty()) throw InputError(path.string(), 0, 0, "obj_file", "missing");
    p.mesh = read_mh_obj(obj);
    if (p.refs.size() != p.mesh.positions.size())
        throw InputError(path.string(), 0, 0, "verts",
                         "expected one line per vertex of " + obj.filename().string() + " (" +
                             std::to_string(p.mesh.positions.size()) + "), got " + std::to_string(p.refs.size()));
    // The material's texture, when the material file is beside the proxy.
    if (!material.empty() && std::filesystem::exists(material)) {
        std::ifstream m(material);
        for (std::string l; std::getline(m, l);) {
            const auto w = split_words(l);
            if (w.size() == 2 && w[0] == "diffuseTexture") p.material_texture = w[1];
        }
    }
    return p;
}

std::vector<glm::vec3> fit_proxy(const MhProxy& proxy, const std::vector<glm::vec3>& base) {
    auto at = [&](std::uint32_t v) {
        if (v >= base.size()) throw InputError(proxy.name + ".mhclo", 0, 0, "verts", "vertex " + std::to_string(v) + " beyond the base mesh");
        return base[v];
    };
    glm::vec3 scale;
    for (int a = 0; a < 3; ++a)
        scale[a] = std::abs(at(proxy.scale_a[a])[a] - at(proxy.scale_b[a])[a]) / proxy.scale_length[a];
    std::vector<glm::vec3> out(proxy.refs.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        const auto& r = proxy.refs[i];
        const auto& w = proxy.ref_weights[i];
        out[i] = w.x * at(r[0]) + w.y * at(r[1]) + w.z * at(r[2]) + proxy.offsets[i] * scale;
    }
    return out;
}

int MhSkeleton::bone_index(const std::string& name) const {
    for (std::size_t i = 0; i < bones.size(); ++i)
        if (bones[i].name == name) return static_cast<int>(i);
    return -1;
}

bool MhSkeleton::descends_from(int b, int ancestor) const {
    for (; b >= 0; b = bones[static_cast<std::size_t>(b)].parent)
        if (b == ancestor) return true;
    return false;
}

MhSkeleton read_skeleton(const std::filesystem::path& mhskel, const std::filesystem::path& mhw) {
    const json s = read_json(mhskel);
    MhSkeleton sk;
    if (!s.contains("bones") || !s["bones"].is_object() || !s.contains("joints") || !s.contains("planes"))
        throw InputError(mhskel.string(), 0, 0, "bones", "expected \"bones\", \"joints\" and \"planes\" objects");
    for (const auto& [name, list] : s["joints"].items()) {
        auto& v = sk.joints[name];
        for (const auto& i : list) v.push_back(i.get<std::uint32_t>());
        if (v.empty()) throw InputError(mhskel.string(), 0, 0, "joints." + name, "expected vertex indices");
    }
    for (const auto& [name, list] : s["planes"].items()) {
        if (!list.is_array() || list.size() != 3)
            throw InputError(mhskel.string(), 0, 0, "planes." + name, "expected three joint names");
        sk.planes[name] = {list[0].get<std::string>(), list[1].get<std::string>(), list[2].get<std::string>()};
    }
    // Parents before children (breadth first from the roots, names sorted for a fixed order).
    std::map<std::string, std::string> parent_of;
    for (const auto& [name, b] : s["bones"].items())
        parent_of[name] = b.value("parent", json()).is_string() ? b["parent"].get<std::string>() : "";
    std::vector<std::string> queue;
    for (const auto& [name, parent] : parent_of)
        if (parent.empty()) queue.push_back(name);
    for (std::size_t q = 0; q < queue.size(); ++q)
        for (const auto& [name, parent] : parent_of)
            if (parent == queue[q]) queue.push_back(name);
    if (queue.size() != parent_of.size())
        throw InputError(mhskel.string(), 0, 0, "bones", "a bone's parent is missing or the hierarchy has a cycle");
    for (const auto& name : queue) {
        const json& b = s["bones"][name];
        MhSkeleton::Bone bone;
        bone.name = name;
        bone.parent = parent_of[name].empty() ? -1 : sk.bone_index(parent_of[name]);
        bone.head_joint = json_string(b, "head");
        bone.tail_joint = json_string(b, "tail");
        bone.plane = b.value("rotation_plane", json()).is_string() ? b["rotation_plane"].get<std::string>() : "";
        for (const auto* j : {&bone.head_joint, &bone.tail_joint})
            if (!sk.joints.count(*j))
                throw InputError(mhskel.string(), 0, 0, "bones." + name, "no joint \"" + *j + "\"");
        sk.bones.push_back(bone);
    }
    const json w = read_json(mhw);
    sk.weights.resize(sk.bones.size());
    if (!w.contains("weights") || !w["weights"].is_object())
        throw InputError(mhw.string(), 0, 0, "weights", "expected an object of bone weights");
    for (const auto& [name, list] : w["weights"].items()) {
        const int b = sk.bone_index(name);
        if (b < 0) continue;  // weights of bones this skeleton lacks
        for (const auto& pair : list) {
            if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_unsigned() || !pair[1].is_number())
                throw InputError(mhw.string(), 0, 0, "weights." + name, "expected [vertex, weight] pairs, got " + pair.dump());
            sk.weights[static_cast<std::size_t>(b)].push_back({pair[0].get<std::uint32_t>(), pair[1].get<float>()});
        }
    }
    return sk;
}

glm::vec3 joint_position(const MhSkeleton& skeleton, const std::string& joint, const std::vector<glm::vec3>& base) {
    const auto& list = skeleton.joints.at(joint);
    glm::dvec3 sum(0.0);
    for (auto v : list) {
        if (v >= base.size()) throw InputError("skeleton", 0, 0, "joints." + joint, "vertex beyond the base mesh");
        sum += glm::dvec3(base[v]);
    }
    return glm::vec3(sum / double(list.size()));
}

std::vector<glm::mat4> rest_frames(const MhSkeleton& skeleton, const std::vector<glm::vec3>& base) {
    std::vector<glm::mat4> out;
    for (const auto& b : skeleton.bones) {
        const glm::vec3 head = joint_position(skeleton, b.head_joint, base);
        const glm::vec3 tail = joint_position(skeleton, b.tail_joint, base);
        glm::vec3 normal(0.0f, 1.0f, 0.0f);
        const auto plane = skeleton.planes.find(b.plane);
        if (plane != skeleton.planes.end()) {
            const glm::vec3 p1 = joint_position(skeleton, plane->second[0], base);
            const glm::vec3 p2 = joint_position(skeleton, plane->second[1], base);
            const glm::vec3 p3 = joint_position(skeleton, plane->second[2], base);
            const glm::vec3 n = glm::cross(glm::normalize(p3 - p2), glm::normalize(p2 - p1));
            if (glm::length(n) > 1e-8f) normal = glm::normalize(n);
        }
        const glm::vec3 y = glm::normalize(tail - head);
        const glm::vec3 z = glm::normalize(glm::cross(normal, y));
        const glm::vec3 x = glm::normalize(glm::cross(y, z));
        glm::mat4 m(1.0f);
        m[0] = glm::vec4(x, 0.0f);
        m[1] = glm::vec4(y, 0.0f);
        m[2] = glm::vec4(z, 0.0f);
        m[3] = glm::vec4(head, 1.0f);
        out.push_back(m);
    }
    return out;
}

std::map<std::string, MhPose> read_pose_units(const std::filesystem::path& bvh, const std::filesystem::path& json_path) {
    const json names_doc = read_json(json_path);
    if (!names_doc.contains("framemapping") || !names_doc["framemapping"].is_array())
        throw InputError(json_path.string(), 0, 0, "framemapping", "expected an array of pose unit names");
    std::vector<std::string> names;
    for (const auto& n : names_doc["framemapping"]) names.push_back(n.get<std::string>());

    std::ifstream in(bvh);
    if (!in) throw InputError(bvh, "cannot open: no such file");
    struct Joint {
        std::string name;
        std::vector<std::string> channels;
        glm::vec3 offset{0.0f};
        int parent = -1;
    };
    std::vector<Joint> joints;
    std::vector<int> stack;
    std::string line;
    int n = 0;
    int pending = -1;  // the joint whose block is being read
    bool motion = false;
    while (!motion && std::getline(in, line)) {
        ++n;
        const auto w = split_words(line);
        if (w.empty()) continue;
        if (w[0] == "ROOT" || w[0] == "JOINT") {
            if (w.size() < 2) throw InputError(bvh.string(), n, 1, w[0], "expected a joint name");
            joints.push_back({w[1], {}, glm::vec3(0.0f), stack.empty() ? -1 : stack.back()});
            pending = static_cast<int>(joints.size() - 1);
        } else if (w[0] == "End") {
            pending = -2;  // an end site: its offset is not needed
        } else if (w[0] == "{") {
            stack.push_back(pending);
        } else if (w[0] == "}") {
            if (stack.empty()) throw InputError(bvh.string(), n, 1, "}", "unbalanced braces");
            stack.pop_back();
        } else if (w[0] == "OFFSET") {
            if (w.size() != 4) throw InputError(bvh.string(), n, 1, "OFFSET", "expected 3 numbers");
            if (!stack.empty() && stack.back() >= 0)
                joints[static_cast<std::size_t>(stack.back())].offset = {
                    number(w[1], bvh, n, "OFFSET"), number(w[2], bvh, n, "OFFSET"), number(w[3], bvh, n, "OFFSET")};
        } else if (w[0] == "CHANNELS") {
            if (stack.empty() || stack.back() < 0) throw InputError(bvh.string(), n, 1, "CHANNELS", "outside a joint");
            auto& j = joints[static_cast<std::size_t>(stack.back())];
            j.channels.assign(w.begin() + 2, w.end());
            if (w.size() < 2 || std::to_string(j.channels.size()) != w[1])
                throw InputError(bvh.string(), n, 1, "CHANNELS", "the count does not match the names");
        } else if (w[0] == "MOTION") {
            motion = true;
        }
    }
    // Parents are resolved through the block stack; joints[k].parent refers
    // to the enclosing joint block.
    if (!motion) throw InputError(bvh.string(), n, 1, "MOTION", "missing");
    int frames = 0;
    while (std::getline(in, line)) {
        ++n;
        const auto w = split_words(line);
        if (w.size() >= 2 && w[0] == "Frames:") frames = static_cast<int>(number(w[1], bvh, n, "Frames"));
        if (!w.empty() && w[0] == "Frame") break;
    }
    // Z-up files (MakeHuman's test: the spine's direction is mostly along z)
    // are turned into the mesh's Y-up frame: (x, y, z) → (x, z, −y).
    bool z_up = false;
    for (const auto& j : joints)
        if (j.name == "spine01" || j.name == "head") {
            for (const auto& c : joints)
                if (c.parent >= 0 && joints[static_cast<std::size_t>(c.parent)].name == j.name) {
                    z_up = std::abs(c.offset.z) > std::abs(c.offset.y);
                    break;
                }
            break;
        }
    std::size_t channel_count = 0;
    for (const auto& j : joints) channel_count += j.channels.size();
    std::map<std::string, MhPose> units;
    for (int f = 0; f < frames && std::getline(in, line); ++f) {
        ++n;
        const auto w = split_words(line);
        if (w.size() != channel_count)
            throw InputError(bvh.string(), n, 1, "MOTION", "expected " + std::to_string(channel_count) + " values, got " +
                                                               std::to_string(w.size()));
        if (static_cast<std::size_t>(f) >= names.size()) break;
        MhPose pose;
        std::size_t k = 0;
        for (const auto& j : joints) {
            glm::mat4 r(1.0f);
            bool any = false;
            for (const auto& c : j.channels) {
                const float value = number(w[k++], bvh, n, c);
                if (c.size() != 9 || c.substr(1) != "rotation") continue;
                if (value != 0.0f) any = true;
                float angle = glm::radians(value);
                glm::vec3 axis(c[0] == 'X', c[0] == 'Y', c[0] == 'Z');
                if (z_up && c[0] == 'Y') axis = {0, 0, 1}, angle = -angle;
                else if (z_up && c[0] == 'Z') axis = {0, 1, 0};
                // Channels compose left to right: R = R_first · R_second · R_third.
                r = r * glm::rotate(glm::mat4(1.0f), angle, axis);
            }
            if (any) pose[j.name] = glm::mat3(r);
        }
        units[names[static_cast<std::size_t>(f)]] = std::move(pose);
    }
    if (units.size() < std::min<std::size_t>(names.size(), static_cast<std::size_t>(frames)))
        throw InputError(bvh.string(), n, 1, "MOTION", "fewer frames than the header says");
    return units;
}

std::vector<glm::mat4> skinning_matrices(const MhSkeleton& skeleton, const std::vector<glm::mat4>& rest,
                                         const MhPose& pose) {
    const std::size_t nb = skeleton.bones.size();
    std::vector<glm::mat4> global(nb), out(nb);
    for (std::size_t b = 0; b < nb; ++b) {
        glm::mat4 local(1.0f);
        const auto it = pose.find(skeleton.bones[b].name);
        if (it != pose.end()) {
            // World-axis rotation → rotation in the bone's own rest frame.
            const glm::mat3 frame(rest[b]);
            local = glm::mat4(glm::transpose(frame) * it->second * frame);
        }
        const int p = skeleton.bones[b].parent;
        global[b] = p < 0 ? rest[b] * local
                          : global[static_cast<std::size_t>(p)] * (glm::inverse(rest[static_cast<std::size_t>(p)]) * rest[b]) * local;
        out[b] = global[b] * glm::inverse(rest[b]);
    }
    return out;
}

std::vector<glm::vec3> skin(const MhSkeleton& skeleton, const std::vector<glm::mat4>& matrices,
                            const std::vector<glm::vec3>& base) {
    std::vector<glm::dvec3> sum(base.size(), glm::dvec3(0.0));
    std::vector<double> total(base.size(), 0.0);
    for (std::size_t b = 0; b < skeleton.bones.size(); ++b)
        for (const auto& [v, w] : skeleton.weights[b]) {
            if (v >= base.size()) continue;
            sum[v] += double(w) * glm::dvec3(matrices[b] * glm::vec4(base[v], 1.0f));
            total[v] += w;
        }
    std::vector<glm::vec3> out(base.size());
    for (std::size_t v = 0; v < base.size(); ++v) out[v] = total[v] > 1e-9 ? glm::vec3(sum[v] / total[v]) : base[v];
    return out;
}

}  // namespace avsi::stimuli::detail
