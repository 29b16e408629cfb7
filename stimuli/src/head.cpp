// Head loading (OBJ through tinyobjloader, rig JSON through nlohmann_json),
// rig weights (group membership, Laplacian smoothing, spatial falloffs) and
// posing (Parke-style weighted transforms; Parke 1982, Beskow 1995 §2).
#include "avsi/stimuli/head.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <map>
#include <numeric>
#include <set>
#include <span>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>
#include <tiny_obj_loader.h>

#include "avsi/core/checks.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/stimuli/image_io.h"
#include "rig_reader.h"
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

// Texture coordinates per vertex, when every corner of a vertex has the same
// one; `uv_conflict` names the first vertex with two.
struct ObjRead {
    HeadMesh mesh;
    std::optional<std::size_t> uv_conflict;
};

// A head fits in 10 m: a coordinate, size or factor in a mesh or rig
// beyond ±10⁴ (mm) is garbage, not a head.
constexpr double k_max_head_mm = 1e4;

ObjRead read_obj(const std::filesystem::path& path) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = true;
    config.vertex_color = true;
    tinyobj::ObjReader reader;
    if (!std::filesystem::exists(path)) throw InputError(path, "cannot open: no such file");
    // tinyobjloader reads a coordinate it cannot parse ("nan", "1e999", "x")
    // as 0: check every vertex line first, with its line number.
    {
        const std::string text = read_text_file(path);
        std::size_t pos = 0;
        for (int line = 1; pos < text.size(); ++line) {
            const std::size_t end = std::min(text.find('\n', pos), text.size());
            const std::string_view l(text.data() + pos, end - pos);
            if (l.size() > 2 && l[0] == 'v' && (l[1] == ' ' || l[1] == '\t')) {
                std::size_t i = 2;
                for (int k = 0; i < l.size(); ++k) {
                    while (i < l.size() && std::isspace(static_cast<unsigned char>(l[i]))) ++i;
                    std::size_t j = i;
                    while (j < l.size() && !std::isspace(static_cast<unsigned char>(l[j]))) ++j;
                    if (j == i) break;
                    const auto value = parse_double(l.substr(i, j - i));
                    const std::string field = k < 3 ? std::string("vertex ") + "xyz"[k] : "vertex colour";
                    if (!value)
                        throw InputError(path.string(), line, static_cast<int>(i) + 1, field,
                                         fmt::format("expected a number, got \"{}\"", excerpt(l.substr(i, j - i))));
                    require_in_range(*value, -k_max_head_mm, k_max_head_mm, at(path.string(), line, static_cast<int>(i) + 1, field),
                                     "a coordinate in mm");
                    i = j;
                }
            }
            pos = end + 1;
        }
    }
    if (!reader.ParseFromFile(path.string(), config))
        throw InputError(path, "not a readable OBJ mesh: " + reader.Error());
    const auto& attrib = reader.GetAttrib();
    HeadMesh mesh;
    const std::size_t n = attrib.vertices.size() / 3;
    if (n == 0) throw InputError(path, "the mesh has no vertices");
    mesh.positions.resize(n);
    mesh.colors.resize(n, glm::vec3(1.0f));
    for (std::size_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k)
            require_in_range(attrib.vertices[3 * i + k], -k_max_head_mm, k_max_head_mm,
                             at(path.string(), 0, 0, fmt::format("vertex {} {}", i + 1, "xyz"[k])),
                             "a coordinate in mm");
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
    ObjRead result;
    // Texture coordinates, one per vertex (the head format's convention).
    if (!attrib.texcoords.empty()) {
        mesh.uvs.assign(n, glm::vec2(0.0f));
        std::vector<char> seen(n, 0);
        for (const auto& shape : reader.GetShapes())
            for (const auto& idx : shape.mesh.indices) {
                if (idx.texcoord_index < 0 || std::size_t(idx.texcoord_index) * 2 + 1 >= attrib.texcoords.size()) continue;
                const glm::vec2 uv{attrib.texcoords[2 * std::size_t(idx.texcoord_index)],
                                   attrib.texcoords[2 * std::size_t(idx.texcoord_index) + 1]};
                const auto v = static_cast<std::size_t>(idx.vertex_index);
                if (seen[v] && mesh.uvs[v] != uv && !result.uv_conflict) result.uv_conflict = v;
                mesh.uvs[v] = uv;
                seen[v] = 1;
            }
    }
    result.mesh = std::move(mesh);
    return result;
}

// A group's material when the rig names none: by its name (the procedural
// heads' conventions: eyes glossy, teeth and lips moist, the cavity dark and matt).
Material default_material(const std::string& g) {
    Material m;
    if (g == "eyes") m.specular = 0.6f, m.shininess = 90.0f;
    else if (g.find("teeth") != std::string::npos) m.specular = 0.25f, m.shininess = 40.0f;
    else if (g.find("lip") != std::string::npos && g.find("lids") == std::string::npos) m.specular = 0.18f, m.shininess = 30.0f;
    else if (g.find("inner") != std::string::npos) m.specular = 0.2f, m.shininess = 30.0f;
    else if (g.find("cavity") != std::string::npos) m.specular = 0.02f;
    else if (g == "tongue") m.specular = 0.2f, m.shininess = 30.0f;
    return m;
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
        return {number(j[0], field + "[0]"), number(j[1], field + "[1]"), number(j[2], field + "[2]")};
    }
    float number(const json& j, const std::string& field) {
        if (!j.is_number()) {
            problem(field, "expected a number, got " + j.dump());
            return 0.0f;
        }
        const double v = j.get<double>();
        if (!(std::abs(v) <= k_max_head_mm)) {
            problem(field, fmt::format("expected a number in [{}, {}] (mm or a factor), got {}", -k_max_head_mm,
                                       k_max_head_mm, v));
            return 0.0f;
        }
        return static_cast<float>(v);
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
        // Each pass visits every edge: bounded, so a number cannot make the rig hang.
        const json smooth_value = region.value("smooth", json(0));
        int smooth = 0;
        if (!smooth_value.is_number_integer() || smooth_value.get<long long>() < 0 || smooth_value.get<long long>() > 1000)
            rig.problem(field + ".smooth", "expected an integer in [0, 1000], got " + smooth_value.dump());
        else
            smooth = smooth_value.get<int>();
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

// The rig's "articulation" section: vertex indices of the landmarks the
// articulation measures use. Every field is required once the section exists.
ArticulationLandmarks read_articulation(const json& a, const HeadMesh& mesh, RigReader& rig) {
    ArticulationLandmarks L;
    const std::size_t n = mesh.positions.size();
    auto index = [&](const json& j, const std::string& field, std::uint32_t& out) {
        if (!j.is_number_unsigned() || j.get<std::uint64_t>() >= n) {
            rig.problem(field, "expected a vertex index in [0, " + std::to_string(n) + "), got " + j.dump());
            return false;
        }
        out = static_cast<std::uint32_t>(j.get<std::uint64_t>());
        return true;
    };
    auto list = [&](const char* name, std::vector<std::uint32_t>& out, std::size_t min_size) {
        const std::string field = std::string("articulation.") + name;
        const json& j = a[name];
        if (!j.is_array() || j.size() < min_size) {
            rig.problem(field, "expected an array of at least " + std::to_string(min_size) +
                                   " vertex indices, got " + j.dump().substr(0, 60));
            return;
        }
        for (std::size_t k = 0; k < j.size(); ++k) {
            std::uint32_t v = 0;
            if (!index(j[k], field + "[" + std::to_string(k) + "]", v)) return;
            out.push_back(v);
        }
    };
    std::vector<std::string> missing;
    for (const auto& name : articulation_landmark_names())
        if (!a.contains(name)) missing.push_back(name);
    if (!missing.empty()) {
        std::string names;
        for (const auto& m : missing) names += (names.empty() ? "" : ", ") + m;
        rig.problem("articulation", "missing landmark(s): " + names);
        return L;
    }
    list("upper_lip_contour", L.upper_lip_contour, 3);
    list("lower_lip_contour", L.lower_lip_contour, 3);
    if (L.upper_lip_contour.size() != L.lower_lip_contour.size())
        rig.problem("articulation.lower_lip_contour",
                    "expected as many points as upper_lip_contour (" + std::to_string(L.upper_lip_contour.size()) +
                        "), got " + std::to_string(L.lower_lip_contour.size()));
    const json& corners = a["mouth_corners"];
    if (!corners.is_array() || corners.size() != 2)
        rig.problem("articulation.mouth_corners", "expected [left, right] vertex indices, got " + corners.dump());
    else {
        index(corners[0], "articulation.mouth_corners[0]", L.mouth_corner_left);
        index(corners[1], "articulation.mouth_corners[1]", L.mouth_corner_right);
    }
    index(a["upper_lip_point"], "articulation.upper_lip_point", L.upper_lip_point);
    index(a["lower_lip_point"], "articulation.lower_lip_point", L.lower_lip_point);
    list("upper_incisor_edge", L.upper_incisor_edge, 2);
    list("lower_incisor_edge", L.lower_incisor_edge, 2);
    list("lower_lip_surface", L.lower_lip_surface, 1);
    auto axis = [&](const char* name, glm::vec3& out) {
        const glm::vec3 v = rig.vec3(a[name], std::string("articulation.") + name);
        if (!(glm::length(v) > 0.0f)) rig.problem(std::string("articulation.") + name, "expected a non-zero axis");
        else out = glm::normalize(v);
    };
    axis("up", L.up);
    axis("forward", L.forward);
    if (std::abs(glm::dot(L.up, L.forward)) > 0.05f)
        rig.problem("articulation.forward", "expected an axis perpendicular to articulation.up");
    return L;
}

// The rig's "lip_contact" section (see LipContact in head.h).
LipContact read_lip_contact(const json& c, const Head& head, RigReader& rig) {
    LipContact contact;
    const auto& a = *head.articulation;
    const auto& pos = head.mesh.positions;
    const glm::vec3 lateral = glm::normalize(glm::cross(a.up, a.forward));
    const float reach = rig.number(c.value("reach_mm", json()), "lip_contact.reach_mm");
    if (!(reach > 0.0f)) rig.problem("lip_contact.reach_mm", "expected a positive distance");
    const std::size_t n = a.upper_lip_contour.size();
    for (std::size_t i = 0; i < n; ++i) contact.pair_order.push_back(i);
    contact.up = a.up;
    contact.mesh.upper = a.upper_lip_contour;
    contact.mesh.lower = a.lower_lip_contour;
    auto lat = [&](std::size_t i) {
        return 0.5f * (glm::dot(pos[a.upper_lip_contour[i]], lateral) + glm::dot(pos[a.lower_lip_contour[i]], lateral));
    };
    std::sort(contact.pair_order.begin(), contact.pair_order.end(),
              [&](std::size_t x, std::size_t y) { return lat(x) < lat(y); });
    for (auto i : contact.pair_order) contact.pair_lateral.push_back(lat(i));
    const float l0 = glm::dot(pos[a.mouth_corner_left], lateral), l1 = glm::dot(pos[a.mouth_corner_right], lateral);
    contact.corner_lateral_min = std::min(l0, l1);
    contact.corner_lateral_max = std::max(l0, l1);
    // A lip's edge height at a lateral position, at rest (linear between pairs).
    auto edge_height = [&](const std::vector<std::uint32_t>& contour, float x) {
        const auto& L = contact.pair_lateral;
        std::size_t k = std::upper_bound(L.begin(), L.end(), x) - L.begin();
        if (k == 0) return glm::dot(pos[contour[contact.pair_order.front()]], a.up);
        if (k == L.size()) return glm::dot(pos[contour[contact.pair_order.back()]], a.up);
        const float t = (x - L[k - 1]) / std::max(L[k] - L[k - 1], 1e-6f);
        return (1 - t) * glm::dot(pos[contour[contact.pair_order[k - 1]]], a.up) +
               t * glm::dot(pos[contour[contact.pair_order[k]]], a.up);
    };
    for (int side : {1, -1}) {
        const char* name = side > 0 ? "upper" : "lower";
        if (!c.contains(name)) {
            rig.problem(std::string("lip_contact.") + name, "missing: the region of the lip that takes the contact");
            continue;
        }
        const auto w = region_weights(head.mesh, c[name], std::string("lip_contact.") + name, rig);
        const auto& contour = side > 0 ? a.upper_lip_contour : a.lower_lip_contour;
        // The contour points themselves move by their own pair's full half
        // overlap, so the measured pairs meet exactly.
        // The other lip's contour points are that lip's alone.
        std::map<std::uint32_t, int> pair_of;
        for (std::size_t i = 0; i < contour.size(); ++i) pair_of.emplace(contour[i], static_cast<int>(i));
        const auto& other = side > 0 ? a.lower_lip_contour : a.upper_lip_contour;
        const std::set<std::uint32_t> others(other.begin(), other.end());
        for (std::size_t v = 0; v < w.size(); ++v) {
            const auto own = pair_of.find(static_cast<std::uint32_t>(v));
            if ((w[v] <= 1e-4f && own == pair_of.end()) || (own == pair_of.end() && others.count(static_cast<std::uint32_t>(v))))
                continue;
            const float x = glm::dot(pos[v], lateral);
            const float d = std::abs(glm::dot(pos[v], a.up) - edge_height(contour, x));
            const float weight = own != pair_of.end() ? 1.0f : std::min(w[v], 1.0f) * (1.0f - smoothstep(0.0f, reach, d));
            if (weight <= 1e-4f) continue;
            contact.mesh.moved.push_back(static_cast<std::uint32_t>(v));
            contact.mesh.sign_weight.push_back(float(side) * weight);
            contact.mesh.lateral.push_back(x);
            contact.mesh.pair.push_back(own != pair_of.end() ? own->second : -1);
        }
    }
    return contact;
}

}  // namespace

namespace {

// The contact displacement (before weight and side) at rest-lateral x.
float contact_offset(const LipContact& contact, const std::vector<float>& half_overlap, float x) {
    const auto& L = contact.pair_lateral;
    const std::size_t k = static_cast<std::size_t>(std::upper_bound(L.begin(), L.end(), x) - L.begin());
    // Beyond the outermost pairs the overlap falls to zero at the corners.
    if (k == 0) {
        const float t = (x - contact.corner_lateral_min) / std::max(L.front() - contact.corner_lateral_min, 1e-6f);
        return std::clamp(t, 0.0f, 1.0f) * half_overlap[contact.pair_order.front()];
    }
    if (k == L.size()) {
        const float t = (contact.corner_lateral_max - x) / std::max(contact.corner_lateral_max - L.back(), 1e-6f);
        return std::clamp(t, 0.0f, 1.0f) * half_overlap[contact.pair_order.back()];
    }
    const float t = (x - L[k - 1]) / std::max(L[k] - L[k - 1], 1e-6f);
    return (1 - t) * half_overlap[contact.pair_order[k - 1]] + t * half_overlap[contact.pair_order[k]];
}

}  // namespace

void apply_lip_contact(const LipContact& contact, const LipContactPoints& points, std::vector<glm::vec3>& positions) {
    thread_local std::vector<float> half_overlap;
    half_overlap.resize(points.upper.size());
    bool any = false;
    for (std::size_t i = 0; i < points.upper.size(); ++i) {
        const float o = glm::dot(positions[points.lower[i]] - positions[points.upper[i]], contact.up);
        half_overlap[i] = o > 0.0f ? 0.5f * o : 0.0f;
        any = any || o > 0.0f;
    }
    if (!any) return;
    for (std::size_t k = 0; k < points.moved.size(); ++k) {
        const int pair = points.pair[k];
        const float offset = pair >= 0 ? half_overlap[static_cast<std::size_t>(pair)]
                                       : contact_offset(contact, half_overlap, points.lateral[k]);
        positions[points.moved[k]] += contact.up * (points.sign_weight[k] * offset);
    }
}

const std::vector<std::string>& articulation_landmark_names() {
    static const std::vector<std::string> names{
        "upper_lip_contour", "lower_lip_contour", "mouth_corners",      "upper_lip_point", "lower_lip_point",
        "upper_incisor_edge", "lower_incisor_edge", "lower_lip_surface", "up",              "forward"};
    return names;
}

Head load_head(const std::filesystem::path& obj_path, const std::filesystem::path& rig_path) {
    Head head;
    head.obj_path = obj_path;
    head.rig_path = rig_path;
    auto obj = read_obj(obj_path);
    head.mesh = std::move(obj.mesh);

    const json doc = read_json_file(rig_path);
    with_json_context(rig_path, [&] { detail::read_rig(head, doc, obj.uv_conflict, true); });
    return head;
}

namespace {

// The landmarks (mm); a head without a neck pivot gets the built-in head's,
// placed relative to its other landmarks.
void read_landmarks(const json& doc, RigReader& rig, Landmarks& L) {
    const json lm = doc.value("landmarks", json::object());
    L.left_eye = rig.vec3(lm.value("left_eye", json()), "landmarks.left_eye");
    L.right_eye = rig.vec3(lm.value("right_eye", json()), "landmarks.right_eye");
    L.nose_bottom = rig.vec3(lm.value("nose_bottom", json()), "landmarks.nose_bottom");
    L.mouth_left = rig.vec3(lm.value("mouth_left", json()), "landmarks.mouth_left");
    L.mouth_right = rig.vec3(lm.value("mouth_right", json()), "landmarks.mouth_right");
    L.mouth_middle = rig.vec3(lm.value("mouth_middle", json()), "landmarks.mouth_middle");
    L.head_center = rig.vec3(lm.value("head_center", json()), "landmarks.head_center");
    L.iris_diameter = rig.number(lm.value("iris_diameter", json()), "landmarks.iris_diameter");
    L.head_height = rig.number(lm.value("head_height", json()), "landmarks.head_height");
    if (lm.contains("neck_pivot")) {
        L.neck_pivot = rig.vec3(lm["neck_pivot"], "landmarks.neck_pivot");
        L.has_neck_pivot = true;
    } else {
        // Where the built-in head's pivot lies relative to its landmarks.
        const glm::vec3 eyes = 0.5f * (L.left_eye + L.right_eye);
        L.neck_pivot = glm::vec3(eyes.x, L.nose_bottom.y + 0.25f * (eyes.y - L.nose_bottom.y),
                                 eyes.z - 0.35f * L.head_height);
    }
}

// The texture a rig names, beside the rig file; the mesh must have one
// texture coordinate per vertex.
void read_rig_texture(Head& head, const json& doc, RigReader& rig, std::optional<std::size_t> uv_conflict) {
    if (!doc.contains("texture")) return;
    const auto& rig_path = head.rig_path;
    const auto& obj_path = head.obj_path;
    if (!doc["texture"].is_string()) rig.problem("texture", "expected a PNG file name, got " + doc["texture"].dump());
    else if (head.mesh.uvs.empty()) rig.problem("texture", "the mesh " + obj_path.filename().string() + " has no texture coordinates (vt)");
    else if (uv_conflict)
        rig.problem("texture", "vertex " + std::to_string(*uv_conflict + 1) + " of " + obj_path.filename().string() +
                                   " has two texture coordinates; a textured head needs one per vertex (split the vertex)");
    else {
        const auto path = rig_path.parent_path() / doc["texture"].get<std::string>();
        if (!std::filesystem::is_regular_file(path)) rig.problem("texture", "no such file: " + path.string());
        else {
            head.texture = read_image_rgba(path);
            head.texture_path = path;
        }
    }
}

// Each group's material: the default for its name, with the rig's fields.
void read_materials(Head& head, const json& doc, RigReader& rig) {
    head.materials.resize(head.mesh.group_names.size());
    for (std::size_t g = 0; g < head.materials.size(); ++g) head.materials[g] = default_material(head.mesh.group_names[g]);
    if (doc.contains("materials")) {
        if (!doc["materials"].is_object()) rig.problem("materials", "expected an object of group materials");
        else
            for (const auto& [name, m] : doc["materials"].items()) {
                const std::string field = "materials." + name;
                const int g = head.mesh.group_index(name);
                if (g < 0) {
                    const auto hint = closest_match(name, head.mesh.group_names);
                    rig.problem(field, "no group '" + name + "' in the mesh" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
                    continue;
                }
                Material& mat = head.materials[static_cast<std::size_t>(g)];
                for (const auto& [key, value] : m.items()) {
                    if (key == "specular") mat.specular = rig.number(value, field + ".specular");
                    else if (key == "shininess") mat.shininess = rig.number(value, field + ".shininess");
                    else if (key == "wrap") mat.wrap = rig.number(value, field + ".wrap");
                    else if (key == "blend") {
                        if (!value.is_boolean()) rig.problem(field + "." + key, "expected true or false, got " + value.dump());
                        else mat.blend = value.get<bool>();
                    } else {
                        const auto hint = closest_match(key, {"specular", "shininess", "wrap", "blend"});
                        rig.problem(field + "." + key, "unknown field" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
                    }
                }
                if (mat.specular < 0 || mat.shininess < 1 || mat.wrap < 0 || mat.wrap > 1)
                    rig.problem(field, "expected specular >= 0, shininess >= 1 and wrap in [0, 1]");
            }
    }
}

// Explicit sparse entries (the "weights" of a transform, the vertices of a
// blendshape): vertex indices in [0, n), or none after a problem.
std::vector<std::uint32_t> vertex_list(RigReader& rig, std::size_t n, const json& j, const std::string& f) {
    std::vector<std::uint32_t> out;
    if (!j.is_array()) {
        rig.problem(f, "expected an array of vertex indices");
        return out;
    }
    for (const auto& v : j) {
        if (!v.is_number_unsigned() || v.get<std::uint64_t>() >= n) {
            rig.problem(f, "expected vertex indices in [0, " + std::to_string(n) + "), got " + v.dump());
            return std::vector<std::uint32_t>{};
        }
        out.push_back(static_cast<std::uint32_t>(v.get<std::uint64_t>()));
    }
    return out;
}

// One transform of the rig (`field` names it in messages), or none after a
// problem that leaves it unusable.
std::optional<RigTransform> read_transform(const json& t, const std::string& field, const Head& head, RigReader& rig) {
    const std::vector<std::string>& channels = channel_names();
    RigTransform rt;
    rt.channel = t.value("channel", "");
    const auto it = std::find(channels.begin(), channels.end(), rt.channel);
    if (it == channels.end()) {
        const auto hint = closest_match(rt.channel, channels);
        rig.problem(field + ".channel", "expected a parameter name, \"blink\", \"tongue_tip\", \"gaze_left\", \"gaze_up\", \"brow_inner_raise\", \"brow_outer_raise\" or \"cheek_raise\", got \"" +
                                            rt.channel + "\"" +
                                            (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
        return std::nullopt;
    }
    rt.channel_index = static_cast<int>(it - channels.begin());
    if (t.contains("side")) {
        const std::string side = t["side"].is_string() ? t["side"].get<std::string>() : t["side"].dump();
        if (side == "positive") rt.side = ChannelSide::Positive;
        else if (side == "negative") rt.side = ChannelSide::Negative;
        else rig.problem(field + ".side", "expected \"positive\" or \"negative\", got " + t["side"].dump());
    }
    if (t.contains("blendshape")) {
        rt.kind = TransformKind::Blendshape;
        const json& b = t["blendshape"];
        rt.vertices = vertex_list(rig, head.mesh.positions.size(), b.value("vertices", json()), field + ".blendshape.vertices");
        const json& o = b.value("offsets", json());
        if (!o.is_array() || o.size() != 3 * rt.vertices.size()) {
            rig.problem(field + ".blendshape.offsets", "expected 3 numbers per vertex (" + std::to_string(3 * rt.vertices.size()) +
                                                            "), got " + (o.is_array() ? std::to_string(o.size()) : o.dump().substr(0, 40)));
            return std::nullopt;
        }
        for (std::size_t k = 0; k < rt.vertices.size(); ++k) {
            if (!o[3 * k].is_number() || !o[3 * k + 1].is_number() || !o[3 * k + 2].is_number()) {
                rig.problem(field + ".blendshape.offsets", "expected numbers, got " + o[3 * k].dump());
                break;
            }
            const std::string f = field + ".blendshape.offsets";
            rt.offsets.push_back({rig.number(o[3 * k], f), rig.number(o[3 * k + 1], f), rig.number(o[3 * k + 2], f)});
        }
        rt.weights.assign(rt.vertices.size(), 1.0f);
        if (t.contains("region")) {
            const auto w = region_weights(head.mesh, t["region"], field + ".region", rig);
            for (std::size_t k = 0; k < rt.vertices.size(); ++k) rt.weights[k] = std::min(w[rt.vertices[k]], 1.0f);
        }
        return rt;
    }
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
        rig.problem(field, "expected one of 'rotate', 'translate', 'scale', 'blendshape'");
        return std::nullopt;
    }
    if (t.contains("weights")) {
        if (t.contains("region")) rig.problem(field, "expected one of 'region' and 'weights', got both");
        const json& w = t["weights"];
        rt.vertices = vertex_list(rig, head.mesh.positions.size(), w.value("vertices", json()), field + ".weights.vertices");
        const json& values = w.value("values", json());
        if (!values.is_array() || values.size() != rt.vertices.size()) {
            rig.problem(field + ".weights.values", "expected one weight per vertex (" + std::to_string(rt.vertices.size()) + ")");
            return std::nullopt;
        }
        for (const auto& v : values) {
            const float x = rig.number(v, field + ".weights.values");
            if (!(x >= 0.0f && x <= 1.0f)) {
                rig.problem(field + ".weights.values", "expected weights in [0, 1], got " + v.dump());
                break;
            }
            rt.weights.push_back(x);
        }
    } else {
        const auto w = region_weights(head.mesh, t.contains("region") ? t["region"] : json::object(), field + ".region", rig);
        for (std::size_t i = 0; i < w.size(); ++i)
            if (w[i] > 1e-4f) {
                rt.vertices.push_back(static_cast<std::uint32_t>(i));
                rt.weights.push_back(std::min(w[i], 1.0f));
            }
    }
    return rt;
}

}  // namespace

namespace detail {

void read_rig(Head& head, const nlohmann::json& doc, std::optional<std::size_t> uv_conflict, bool check_format) {
    RigReader rig{head.rig_path, {}};
    if (check_format && json_string(doc, "format") != "avsi-rig")
        rig.problem("format", "expected \"avsi-rig\", got " + doc.value("format", json()).dump());
    read_landmarks(doc, rig, head.landmarks);
    if (doc.contains("articulation")) {
        if (!doc["articulation"].is_object()) rig.problem("articulation", "expected an object of landmark vertex indices");
        else head.articulation = read_articulation(doc["articulation"], head.mesh, rig);
    }

    if (doc.contains("lip_contact")) {
        if (!head.articulation) rig.problem("lip_contact", "needs the \"articulation\" section's lip contours");
        else if (!doc["lip_contact"].is_object()) rig.problem("lip_contact", "expected an object");
        else if (rig.problems.empty()) head.lip_contact = read_lip_contact(doc["lip_contact"], head, rig);
    }
    read_rig_texture(head, doc, rig, uv_conflict);
    read_materials(head, doc, rig);
    int k = 0;
    for (const auto& t : doc.value("transforms", json::array())) {
        const std::string field = "transforms[" + std::to_string(k++) + "]";
        if (auto rt = read_transform(t, field, head, rig)) head.transforms.push_back(std::move(*rt));
    }
    rig.problems.throw_if_any();
}

}  // namespace detail

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

const std::vector<std::string>& channel_names() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> out;
        for (const auto& info : synth::params()) out.emplace_back(info.name);
        for (const char* n : {"blink", "tongue_tip", "gaze_left", "gaze_up", "brow_inner_raise", "brow_outer_raise",
                              "cheek_raise"})
            out.emplace_back(n);
        AVSI_ASSERT(out.size() == channel_count);
        return out;
    }();
    return names;
}

double Pose::channel(std::size_t c) const {
    AVSI_ASSERT(c < channel_count);
    if (c < synth::param_count) return params[c];
    switch (c) {
        case blink_channel: return blink;
        case tongue_tip_channel: return tongue_tip;
        case gaze_left_channel: return gaze_left;
        case gaze_up_channel: return gaze_up;
        case brow_inner_raise_channel: return brow_inner_raise;
        case brow_outer_raise_channel: return brow_outer_raise;
        default: return cheek_raise;
    }
}

void Pose::set_channel(std::size_t c, double value) {
    AVSI_ASSERT(c < channel_count);
    if (c < synth::param_count) {
        params[c] = value;
        return;
    }
    switch (c) {
        case blink_channel: blink = value; break;
        case tongue_tip_channel: tongue_tip = value; break;
        case gaze_left_channel: gaze_left = value; break;
        case gaze_up_channel: gaze_up = value; break;
        case brow_inner_raise_channel: brow_inner_raise = value; break;
        case brow_outer_raise_channel: brow_outer_raise = value; break;
        default: cheek_raise = value; break;
    }
}

void apply_head_rotation(const Head& head, const glm::quat& rotation, PosedMesh& posed) {
    if (rotation == glm::quat(1.0f, 0.0f, 0.0f, 0.0f)) return;
    const glm::mat3 r = glm::mat3_cast(glm::normalize(rotation));
    const glm::vec3 pivot = head.landmarks.neck_pivot;
    for (auto& p : posed.positions) p = pivot + r * (p - pivot);
    for (auto& n : posed.normals) n = r * n;
}

double channel_amount(const RigTransform& t, const Pose& pose) {
    const double value = pose.channel(static_cast<std::size_t>(t.channel_index));
    switch (t.side) {
        case ChannelSide::Positive: return std::max(value, 0.0);
        case ChannelSide::Negative: return std::min(value, 0.0);
        case ChannelSide::Both: break;
    }
    return value;
}

void apply_transform(const RigTransform& t, float amount, std::span<const std::uint32_t> entries,
                     std::span<const std::uint32_t> targets, std::vector<glm::vec3>& positions) {
    AVSI_ASSERT(entries.size() == targets.size());
    switch (t.kind) {
        case TransformKind::Translate:
            for (std::size_t j = 0; j < entries.size(); ++j) positions[targets[j]] += t.offset * (amount * t.weights[entries[j]]);
            break;
        case TransformKind::Blendshape:
            for (std::size_t j = 0; j < entries.size(); ++j)
                positions[targets[j]] += t.offsets[entries[j]] * (amount * t.weights[entries[j]]);
            break;
        case TransformKind::Scale:
            for (std::size_t j = 0; j < entries.size(); ++j) {
                auto& p = positions[targets[j]];
                p = t.pivot + (p - t.pivot) * (glm::vec3(1.0f) + t.scale * (amount * t.weights[entries[j]]));
            }
            break;
        case TransformKind::Rotate: {
            const float full = glm::radians(t.angle_deg) * amount;
            for (std::size_t j = 0; j < entries.size(); ++j) {
                auto& p = positions[targets[j]];
                const glm::quat q = glm::angleAxis(full * t.weights[entries[j]], t.axis);
                p = t.pivot + q * (p - t.pivot);
            }
            break;
        }
    }
}

void pose_positions(const Head& head, const Pose& pose, std::vector<glm::vec3>& positions) {
    positions = head.mesh.positions;
    thread_local std::vector<std::uint32_t> identity;
    for (const auto& t : head.transforms) {
        const double amount = channel_amount(t, pose);
        if (amount == 0.0) continue;
        if (identity.size() < t.vertices.size()) {
            const auto old = identity.size();
            identity.resize(t.vertices.size());
            std::iota(identity.begin() + std::ptrdiff_t(old), identity.end(), static_cast<std::uint32_t>(old));
        }
        // Every entry onto its own vertex.
        apply_transform(t, static_cast<float>(amount), std::span(identity.data(), t.vertices.size()), t.vertices,
                        positions);
    }
    if (head.lip_contact) apply_lip_contact(*head.lip_contact, head.lip_contact->mesh, positions);
}

void pose_head(const Head& head, const Pose& pose, PosedMesh& out) {
    pose_positions(head, pose, out.positions);
    compute_normals(out.positions, head.mesh.indices, out.normals);
}

}  // namespace avsi::stimuli
