// Head loading (OBJ through tinyobjloader, rig JSON through nlohmann_json),
// rig weights (group membership, Laplacian smoothing, spatial falloffs) and
// posing (Parke-style weighted transforms; Parke 1982, Beskow 1995 §2).
#include "avsi/stimuli/head.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>
#include <tiny_obj_loader.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "smoothstep.h"

namespace avsi::stimuli {

using nlohmann::json;

int HeadMesh::group_index(const std::string& name) const {
    for (std::size_t i = 0; i < group_names.size(); ++i)
        if (group_names[i] == name) return static_cast<int>(i);
    return -1;
}

std::filesystem::path default_head_obj() {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "head" / "head.obj";
}
std::filesystem::path default_head_rig() {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "head" / "head.rig.json";
}
Head load_default_head() { return load_head(default_head_obj(), default_head_rig()); }

namespace {

HeadMesh read_obj(const std::filesystem::path& path) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = true;
    config.vertex_color = true;
    tinyobj::ObjReader reader;
    if (!std::filesystem::exists(path)) throw InputError(path, "cannot open: no such file");
    if (!reader.ParseFromFile(path.string(), config))
        throw InputError(path, "not a readable OBJ mesh: " + reader.Error());
    const auto& attrib = reader.GetAttrib();
    HeadMesh mesh;
    const std::size_t n = attrib.vertices.size() / 3;
    if (n == 0) throw InputError(path, "the mesh has no vertices");
    mesh.positions.resize(n);
    mesh.colors.resize(n, glm::vec3(1.0f));
    for (std::size_t i = 0; i < n; ++i) {
        mesh.positions[i] = {attrib.vertices[3 * i], attrib.vertices[3 * i + 1],
                             attrib.vertices[3 * i + 2]};
        if (attrib.colors.size() >= 3 * n)
            mesh.colors[i] = {attrib.colors[3 * i], attrib.colors[3 * i + 1], attrib.colors[3 * i + 2]};
    }
    for (const auto& shape : reader.GetShapes()) {
        int group = mesh.group_index(shape.name);
        if (group < 0) {
            group = static_cast<int>(mesh.group_names.size());
            mesh.group_names.push_back(shape.name);
        }
        std::size_t offset = 0;
        for (const auto fv : shape.mesh.num_face_vertices) {
            if (fv != 3) throw InputError(path, "group '" + shape.name + "': a face is not a triangle");
            for (std::size_t k = 0; k < 3; ++k) {
                const int vi = shape.mesh.indices[offset + k].vertex_index;
                if (vi < 0 || static_cast<std::size_t>(vi) >= n)
                    throw InputError(path, "group '" + shape.name + "': vertex index out of range");
                mesh.indices.push_back(static_cast<std::uint32_t>(vi));
            }
            mesh.triangle_group.push_back(group);
            offset += 3;
        }
    }
    if (mesh.indices.empty()) throw InputError(path, "the mesh has no faces");
    return mesh;
}

struct RigReader {
    std::filesystem::path path;
    DiagnosticList problems;

    void problem(const std::string& field, const std::string& message) {
        problems.add(path.string(), 0, 0, field, message);
    }
    glm::vec3 vec3(const json& j, const std::string& field) {
        if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() ||
            !j[2].is_number()) {
            problem(field, "expected an array of 3 numbers, got " + j.dump());
            return glm::vec3(0.0f);
        }
        return {j[0].get<float>(), j[1].get<float>(), j[2].get<float>()};
    }
    float number(const json& j, const std::string& field) {
        if (!j.is_number()) {
            problem(field, "expected a number, got " + j.dump());
            return 0.0f;
        }
        return j.get<float>();
    }
};

// Weights of one region: the fraction of each vertex's triangles that lie in
// the region's groups, smoothed over the mesh edges, times spatial falloffs.
std::vector<float> term_weights(const HeadMesh& mesh, const json& region, const std::string& field,
                                RigReader& rig) {
    const std::size_t n = mesh.positions.size();
    std::vector<float> w(n, 1.0f);
    if (region.contains("groups")) {
        std::vector<bool> in_group(mesh.group_names.size(), false);
        for (const auto& g : region["groups"]) {
            const std::string name = g.is_string() ? g.get<std::string>() : g.dump();
            const int gi = mesh.group_index(name);
            if (gi < 0) {
                const auto hint = closest_match(name, mesh.group_names);
                rig.problem(field + ".groups",
                            "no group '" + name + "' in the mesh" +
                                (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
                continue;
            }
            in_group[static_cast<std::size_t>(gi)] = true;
        }
        std::vector<float> inside(n, 0.0f), total(n, 0.0f);
        for (std::size_t t = 0; t < mesh.triangle_group.size(); ++t) {
            const float member = in_group[static_cast<std::size_t>(mesh.triangle_group[t])] ? 1.0f : 0.0f;
            for (int k = 0; k < 3; ++k) {
                inside[mesh.indices[3 * t + k]] += member;
                total[mesh.indices[3 * t + k]] += 1.0f;
            }
        }
        for (std::size_t i = 0; i < n; ++i) w[i] = total[i] > 0 ? inside[i] / total[i] : 0.0f;
        const int smooth = region.value("smooth", 0);
        if (smooth > 0) {
            std::vector<std::set<std::uint32_t>> neighbours(n);
            for (std::size_t t = 0; t < mesh.indices.size(); t += 3)
                for (int a = 0; a < 3; ++a)
                    for (int b = 0; b < 3; ++b)
                        if (a != b) neighbours[mesh.indices[t + a]].insert(mesh.indices[t + b]);
            std::vector<float> next(n);
            for (int it = 0; it < smooth; ++it) {
                for (std::size_t i = 0; i < n; ++i) {
                    float sum = 0.0f;
                    for (auto j : neighbours[i]) sum += w[j];
                    next[i] = neighbours[i].empty() ? w[i]
                                                    : 0.5f * w[i] + 0.5f * sum / float(neighbours[i].size());
                }
                w.swap(next);
            }
        }
    }
    if (region.contains("falloff")) {
        int k = 0;
        for (const auto& f : region["falloff"]) {
            const std::string ff = field + ".falloff[" + std::to_string(k++) + "]";
            if (f.contains("ellipsoid")) {
                const auto& e = f["ellipsoid"];
                const glm::vec3 c = rig.vec3(e.value("center", json()), ff + ".center");
                const glm::vec3 r = rig.vec3(e.value("radii", json()), ff + ".radii");
                const float inner = rig.number(e.value("inner", json(0.0)), ff + ".inner");
                if (r.x <= 0 || r.y <= 0 || r.z <= 0) {
                    rig.problem(ff + ".radii", "expected positive radii");
                    continue;
                }
                if (inner < 0 || inner >= 1) rig.problem(ff + ".inner", "expected a number in [0, 1)");
                const bool invert = e.value("invert", false);
                for (std::size_t i = 0; i < n; ++i) {
                    const float d = glm::length((mesh.positions[i] - c) / r);
                    const float v = 1.0f - smoothstep(inner, 1.0f, d);
                    w[i] *= invert ? 1.0f - v : v;
                }
            } else if (f.contains("halfspace")) {
                const auto& h = f["halfspace"];
                const glm::vec3 o = rig.vec3(h.value("origin", json()), ff + ".origin");
                glm::vec3 nrm = rig.vec3(h.value("normal", json()), ff + ".normal");
                const float width = rig.number(h.value("width", json(0.0)), ff + ".width");
                if (glm::length(nrm) <= 0 || width <= 0) {
                    rig.problem(ff, "expected a non-zero normal and a positive width");
                    continue;
                }
                nrm = glm::normalize(nrm);
                for (std::size_t i = 0; i < n; ++i)
                    w[i] *= smoothstep(-0.5f * width, 0.5f * width, glm::dot(mesh.positions[i] - o, nrm));
            } else {
                rig.problem(ff, "expected an 'ellipsoid' or 'halfspace' falloff, got " + f.dump());
            }
        }
    }
    const float scale = region.contains("scale") ? rig.number(region["scale"], field + ".scale") : 1.0f;
    for (auto& x : w) x *= scale;
    return w;
}

// A region is one term or an array of terms whose weights are summed and
// clamped to [0, 1] (e.g. "the lower lip, minus half near the corners").
std::vector<float> region_weights(const HeadMesh& mesh, const json& region, const std::string& field,
                                  RigReader& rig) {
    if (!region.is_array()) return term_weights(mesh, region, field, rig);
    std::vector<float> w(mesh.positions.size(), 0.0f);
    for (std::size_t k = 0; k < region.size(); ++k) {
        const auto t = term_weights(mesh, region[k], field + "[" + std::to_string(k) + "]", rig);
        for (std::size_t i = 0; i < w.size(); ++i) w[i] += t[i];
    }
    for (auto& x : w) x = std::clamp(x, 0.0f, 1.0f);
    return w;
}

}  // namespace

Head load_head(const std::filesystem::path& obj_path, const std::filesystem::path& rig_path) {
    Head head;
    head.obj_path = obj_path;
    head.rig_path = rig_path;
    head.mesh = read_obj(obj_path);

    json doc;
    try {
        doc = json::parse(read_text_file(rig_path));
    } catch (const json::parse_error& e) {
        throw InputError(rig_path, std::string("not valid JSON: ") + e.what());
    }
    RigReader rig{rig_path, {}};
    if (doc.value("format", "") != "avsi-rig")
        rig.problem("format", "expected \"avsi-rig\", got " + doc.value("format", json()).dump());

    const json lm = doc.value("landmarks", json::object());
    auto& L = head.landmarks;
    L.left_eye = rig.vec3(lm.value("left_eye", json()), "landmarks.left_eye");
    L.right_eye = rig.vec3(lm.value("right_eye", json()), "landmarks.right_eye");
    L.nose_bottom = rig.vec3(lm.value("nose_bottom", json()), "landmarks.nose_bottom");
    L.mouth_left = rig.vec3(lm.value("mouth_left", json()), "landmarks.mouth_left");
    L.mouth_right = rig.vec3(lm.value("mouth_right", json()), "landmarks.mouth_right");
    L.mouth_middle = rig.vec3(lm.value("mouth_middle", json()), "landmarks.mouth_middle");
    L.head_center = rig.vec3(lm.value("head_center", json()), "landmarks.head_center");
    L.iris_diameter = rig.number(lm.value("iris_diameter", json()), "landmarks.iris_diameter");
    L.head_height = rig.number(lm.value("head_height", json()), "landmarks.head_height");

    std::vector<std::string> channels;
    for (const auto& info : synth::params()) channels.emplace_back(info.name);
    channels.emplace_back("blink");

    int k = 0;
    for (const auto& t : doc.value("transforms", json::array())) {
        const std::string field = "transforms[" + std::to_string(k++) + "]";
        RigTransform rt;
        rt.channel = t.value("channel", "");
        const auto it = std::find(channels.begin(), channels.end(), rt.channel);
        if (it == channels.end()) {
            const auto hint = closest_match(rt.channel, channels);
            rig.problem(field + ".channel", "expected a parameter name or \"blink\", got \"" +
                                                rt.channel + "\"" +
                                                (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
            continue;
        }
        rt.channel_index = static_cast<int>(it - channels.begin());
        if (t.contains("rotate")) {
            rt.kind = TransformKind::Rotate;
            rt.pivot = rig.vec3(t["rotate"].value("pivot", json()), field + ".rotate.pivot");
            rt.axis = rig.vec3(t["rotate"].value("axis", json()), field + ".rotate.axis");
            rt.angle_deg = rig.number(t["rotate"].value("angle_deg", json()), field + ".rotate.angle_deg");
            if (glm::length(rt.axis) <= 0) rig.problem(field + ".rotate.axis", "expected a non-zero axis");
            else rt.axis = glm::normalize(rt.axis);
        } else if (t.contains("translate")) {
            rt.kind = TransformKind::Translate;
            rt.offset = rig.vec3(t["translate"], field + ".translate");
        } else if (t.contains("scale")) {
            rt.kind = TransformKind::Scale;
            rt.pivot = rig.vec3(t["scale"].value("pivot", json()), field + ".scale.pivot");
            rt.scale = rig.vec3(t["scale"].value("factor", json()), field + ".scale.factor");
        } else {
            rig.problem(field, "expected one of 'rotate', 'translate', 'scale'");
            continue;
        }
        const auto w = region_weights(head.mesh, t.contains("region") ? t["region"] : json::object(), field + ".region", rig);
        for (std::size_t i = 0; i < w.size(); ++i)
            if (w[i] > 1e-4f) {
                rt.vertices.push_back(static_cast<std::uint32_t>(i));
                rt.weights.push_back(std::min(w[i], 1.0f));
            }
        head.transforms.push_back(std::move(rt));
    }
    rig.problems.throw_if_any();
    return head;
}

Fapu fapu(const Head& head) {
    const auto& L = head.landmarks;
    Fapu f;
    f.es = glm::length(L.left_eye - L.right_eye);
    f.ens = 0.5f * (L.left_eye.y + L.right_eye.y) - L.nose_bottom.y;
    f.mns = L.nose_bottom.y - L.mouth_middle.y;
    f.mw = glm::length(L.mouth_left - L.mouth_right);
    f.irisd = L.iris_diameter;
    return f;
}

void compute_normals(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices,
                     std::vector<glm::vec3>& normals) {
    normals.assign(positions.size(), glm::vec3(0.0f));
    for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
        const auto a = indices[t], b = indices[t + 1], c = indices[t + 2];
        // Unnormalised cross product: weights each face by its area.
        const glm::vec3 n = glm::cross(positions[b] - positions[a], positions[c] - positions[a]);
        normals[a] += n;
        normals[b] += n;
        normals[c] += n;
    }
    for (auto& n : normals) {
        const float len = glm::length(n);
        n = len > 0 ? n / len : glm::vec3(0, 0, 1);
    }
}

void pose_head(const Head& head, const Pose& pose, PosedMesh& out) {
    out.positions = head.mesh.positions;
    for (const auto& t : head.transforms) {
        const double amount = static_cast<std::size_t>(t.channel_index) < synth::param_count
                                  ? pose.params[static_cast<std::size_t>(t.channel_index)]
                                  : pose.blink;
        if (amount == 0.0) continue;
        const float a = static_cast<float>(amount);
        switch (t.kind) {
            case TransformKind::Translate:
                for (std::size_t k = 0; k < t.vertices.size(); ++k)
                    out.positions[t.vertices[k]] += t.offset * (a * t.weights[k]);
                break;
            case TransformKind::Scale:
                for (std::size_t k = 0; k < t.vertices.size(); ++k) {
                    auto& p = out.positions[t.vertices[k]];
                    p = t.pivot + (p - t.pivot) * (glm::vec3(1.0f) + t.scale * (a * t.weights[k]));
                }
                break;
            case TransformKind::Rotate: {
                const float full = glm::radians(t.angle_deg) * a;
                for (std::size_t k = 0; k < t.vertices.size(); ++k) {
                    auto& p = out.positions[t.vertices[k]];
                    const glm::quat q = glm::angleAxis(full * t.weights[k], t.axis);
                    p = t.pivot + q * (p - t.pivot);
                }
                break;
            }
        }
    }
    compute_normals(out.positions, head.mesh.indices, out.normals);
}

}  // namespace avsi::stimuli
