// Level of detail (lod.h): the head partitioned into kept triangles (mouth,
// eyes, the rig's landmarks) and the rest, the rest simplified group by group
// by meshoptimizer's quadric-error edge collapses (Garland & Heckbert 1997)
// with the border locked, then the head compacted and re-indexed.
#include "avsi/stimuli/lod.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <meshoptimizer.h>

#include "avsi/core/error.h"

namespace avsi::stimuli {

namespace {

constexpr std::uint32_t k_dropped = std::numeric_limits<std::uint32_t>::max();

std::string lower(std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// The file a head came from, for messages.
std::string head_file(const Head& head) {
    return (head.rig_path.empty() ? head.obj_path : head.rig_path).string();
}

// The vertices the rig reads by index and that must survive (and stay at
// full detail): the articulation landmarks and the lip contact's points.
std::vector<std::uint32_t> indexed_vertices(const Head& head) {
    std::vector<std::uint32_t> out;
    if (head.articulation) {
        const auto& a = *head.articulation;
        for (const auto* list : {&a.upper_lip_contour, &a.lower_lip_contour, &a.upper_incisor_edge,
                                 &a.lower_incisor_edge, &a.lower_lip_surface})
            out.insert(out.end(), list->begin(), list->end());
        out.insert(out.end(), {a.mouth_corner_left, a.mouth_corner_right, a.upper_lip_point, a.lower_lip_point});
    }
    if (head.lip_contact) {
        const auto& m = head.lip_contact->mesh;
        for (const auto* list : {&m.upper, &m.lower, &m.moved}) out.insert(out.end(), list->begin(), list->end());
    }
    return out;
}

// Per vertex: 1 where it lies within `margin` of a `source` vertex (sources
// included), found through a grid of margin-sized cells.
std::vector<char> near_vertices(const HeadMesh& mesh, const std::vector<char>& source, double margin_mm) {
    const float margin = float(margin_mm);
    auto cell = [&](const glm::vec3& p) {
        return glm::ivec3(int(std::floor(p.x / margin)), int(std::floor(p.y / margin)), int(std::floor(p.z / margin)));
    };
    auto key = [](const glm::ivec3& c) {
        return (std::int64_t(c.x) & 0x1fffff) | ((std::int64_t(c.y) & 0x1fffff) << 21) |
               ((std::int64_t(c.z) & 0x1fffff) << 42);
    };
    std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
    for (std::uint32_t v = 0; v < mesh.positions.size(); ++v)
        if (source[v]) grid[key(cell(mesh.positions[v]))].push_back(v);
    std::vector<char> near = source;
    for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) {
        if (near[v]) continue;
        const glm::ivec3 c = cell(mesh.positions[v]);
        for (int dx = -1; dx <= 1 && !near[v]; ++dx)
            for (int dy = -1; dy <= 1 && !near[v]; ++dy)
                for (int dz = -1; dz <= 1 && !near[v]; ++dz) {
                    const auto it = grid.find(key(c + glm::ivec3(dx, dy, dz)));
                    if (it == grid.end()) continue;
                    for (const auto u : it->second)
                        if (glm::length(mesh.positions[u] - mesh.positions[v]) <= margin) {
                            near[v] = 1;
                            break;
                        }
                }
    }
    return near;
}

// The simplifiable triangles of each group and the kept ones, groups in the
// order of their first triangle.
struct Partition {
    std::vector<int> group_order;
    std::vector<std::vector<std::size_t>> kept;  // per group: triangle numbers
    std::vector<std::vector<std::size_t>> rest;
    // per group: the simplifiable triangles within the margin of an
    // alpha-blended layer (the scalp under the hair), simplified apart with
    // the layers' tighter bound
    std::vector<std::vector<std::size_t>> under_layer;
    std::size_t kept_count = 0;
    std::size_t rest_count = 0;
};

// Whether a group is an alpha-blended layer (hair, brows, lashes).
bool is_layer(const Head& head, int group) {
    const auto g = static_cast<std::size_t>(group);
    return g < head.materials.size() && head.materials[g].blend;
}

Partition partition(const Head& head) {
    const auto keep = lod_kept_triangles(head);
    const auto& mesh = head.mesh;
    Partition p;
    p.kept.resize(mesh.group_names.size());
    p.rest.resize(mesh.group_names.size());
    p.under_layer.resize(mesh.group_names.size());
    std::vector<char> layer_vertex(mesh.positions.size(), 0);
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t)
        if (!keep[t] && is_layer(head, mesh.triangle_group[t]))
            for (int k = 0; k < 3; ++k) layer_vertex[mesh.indices[3 * t + std::size_t(k)]] = 1;
    const auto under = near_vertices(mesh, layer_vertex, lod_keep_margin_mm);
    std::vector<char> seen(mesh.group_names.size(), 0);
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const auto g = static_cast<std::size_t>(mesh.triangle_group[t]);
        if (!seen[g]) {
            seen[g] = 1;
            p.group_order.push_back(static_cast<int>(g));
        }
        const bool near_layer = !is_layer(head, mesh.triangle_group[t]) &&
                                (under[mesh.indices[3 * t]] || under[mesh.indices[3 * t + 1]] ||
                                 under[mesh.indices[3 * t + 2]]);
        (keep[t] ? p.kept : near_layer ? p.under_layer : p.rest)[g].push_back(t);
        ++(keep[t] ? p.kept_count : p.rest_count);
    }
    return p;
}

// The rig, landmark indices and lip contact of `head` on the kept vertices
// (`remap`: old index → new, k_dropped for a dropped vertex): each
// transform keeps the entries of the surviving vertices.
void remap_rig(const Head& head, const std::vector<std::uint32_t>& remap, Head& out) {
    for (const auto& t : head.transforms) {
        RigTransform nt = t;
        nt.vertices.clear();
        nt.weights.clear();
        nt.offsets.clear();
        for (std::size_t j = 0; j < t.vertices.size(); ++j) {
            const auto v = remap[t.vertices[j]];
            if (v == k_dropped) continue;
            nt.vertices.push_back(v);
            nt.weights.push_back(t.weights[j]);
            if (!t.offsets.empty()) nt.offsets.push_back(t.offsets[j]);
        }
        out.transforms.push_back(std::move(nt));
    }
    auto map_list = [&](std::vector<std::uint32_t>& list) {
        for (auto& v : list) v = remap[v];
    };
    if (head.articulation) {
        out.articulation = head.articulation;
        auto& a = *out.articulation;
        for (auto* list : {&a.upper_lip_contour, &a.lower_lip_contour, &a.upper_incisor_edge, &a.lower_incisor_edge,
                           &a.lower_lip_surface})
            map_list(*list);
        for (auto* v : {&a.mouth_corner_left, &a.mouth_corner_right, &a.upper_lip_point, &a.lower_lip_point})
            *v = remap[*v];
    }
    if (head.lip_contact) {
        out.lip_contact = head.lip_contact;
        auto& c = out.lip_contact->mesh;
        map_list(c.upper);
        map_list(c.lower);
        map_list(c.moved);  // every moved point is kept (indexed_vertices)
    }
}

// The head with each group's simplifiable triangles reduced towards
// `fraction` of their number (1 = untouched), no collapse beyond
// `max_error_mm` of geometric error.
LodResult simplify(const Head& head, const Partition& p, double fraction, double max_error_mm) {
    const auto& mesh = head.mesh;
    LodResult r;
    r.full_triangles = mesh.triangle_count();
    r.kept_triangles = p.kept_count;
    std::vector<std::uint32_t> indices;
    std::vector<int> groups;
    indices.reserve(mesh.indices.size());
    std::vector<std::uint32_t> local_of(mesh.positions.size(), k_dropped);
    std::vector<std::uint32_t> global_of;
    std::vector<glm::vec3> local_positions;
    std::vector<unsigned int> local_indices, simplified;
    for (const int g : p.group_order) {
        const auto gi = static_cast<std::size_t>(g);
        for (const auto t : p.kept[gi]) {
            for (int k = 0; k < 3; ++k) indices.push_back(mesh.indices[3 * t + std::size_t(k)]);
            groups.push_back(g);
        }
        for (const bool layered : {false, true}) {
            const auto& rest = layered ? p.under_layer[gi] : p.rest[gi];
            if (rest.empty()) continue;
            if (fraction >= 1.0) {
                for (const auto t : rest) {
                    for (int k = 0; k < 3; ++k) indices.push_back(mesh.indices[3 * t + std::size_t(k)]);
                    groups.push_back(g);
                }
                continue;
            }
            // The group's simplifiable part as a mesh of its own, so its border
            // (against the kept triangles and the other groups) is a border the
            // simplifier locks and its error is relative to its own extent.
            global_of.clear();
            local_positions.clear();
            local_indices.clear();
            for (const auto t : rest)
                for (int k = 0; k < 3; ++k) {
                    const auto v = mesh.indices[3 * t + std::size_t(k)];
                    if (local_of[v] == k_dropped) {
                        local_of[v] = static_cast<std::uint32_t>(global_of.size());
                        global_of.push_back(v);
                        local_positions.push_back(mesh.positions[v]);
                    }
                    local_indices.push_back(local_of[v]);
                }
            const auto target = 3 * static_cast<std::size_t>(std::floor(double(rest.size()) * std::max(fraction, 0.0)));
            simplified.resize(local_indices.size());
            // meshoptimizer's errors are relative to the mesh's extent (its scale).
            // Alpha-blended layers (hair) lie just over the skin: they and the
            // skin under them get a quarter of the bound, so the skin does not
            // come through them.
            const double error_bound = layered || is_layer(head, g) ? 0.25 * max_error_mm : max_error_mm;
            const float scale = meshopt_simplifyScale(&local_positions[0].x, local_positions.size(), sizeof(glm::vec3));
            float error = 0.0f;
            const std::size_t n = meshopt_simplify(simplified.data(), local_indices.data(), local_indices.size(),
                                                   &local_positions[0].x, local_positions.size(), sizeof(glm::vec3),
                                                   target, float(error_bound / std::max(double(scale), 1e-9)),
                                                   meshopt_SimplifyLockBorder, &error);
            r.error_mm = std::max(r.error_mm, double(error) * double(scale));
            for (std::size_t i = 0; i < n; ++i) indices.push_back(global_of[simplified[i]]);
            groups.insert(groups.end(), n / 3, g);
            for (const auto v : global_of) local_of[v] = k_dropped;
        }
    }

    // Compaction: the vertices still used (by a triangle or by the rig's
    // indices), in their original order.
    std::vector<char> used(mesh.positions.size(), 0);
    for (const auto v : indices) used[v] = 1;
    for (const auto v : indexed_vertices(head)) used[v] = 1;
    std::vector<std::uint32_t> remap(mesh.positions.size(), k_dropped);
    for (std::uint32_t v = 0; v < mesh.positions.size(); ++v)
        if (used[v]) {
            remap[v] = static_cast<std::uint32_t>(r.source_vertex.size());
            r.source_vertex.push_back(v);
        }

    Head& out = r.head;
    out.materials = head.materials;
    out.texture = head.texture;
    out.landmarks = head.landmarks;
    out.obj_path = head.obj_path;
    out.rig_path = head.rig_path;
    out.texture_path = head.texture_path;
    HeadMesh& m = out.mesh;
    m.group_names = mesh.group_names;
    m.triangle_group = std::move(groups);
    m.indices.reserve(indices.size());
    for (const auto v : indices) m.indices.push_back(remap[v]);
    for (const auto v : r.source_vertex) {
        m.positions.push_back(mesh.positions[v]);
        if (!mesh.colors.empty()) m.colors.push_back(mesh.colors[v]);
        if (!mesh.uvs.empty()) m.uvs.push_back(mesh.uvs[v]);
    }
    remap_rig(head, remap, out);
    r.triangles = m.triangle_count();
    return r;
}

LodResult full_head(const Head& head) {
    LodResult r;
    r.head = head;
    r.source_vertex.resize(head.mesh.positions.size());
    std::iota(r.source_vertex.begin(), r.source_vertex.end(), 0u);
    r.full_triangles = r.triangles = head.mesh.triangle_count();
    const auto keep = lod_kept_triangles(head);
    r.kept_triangles = static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1));
    return r;
}

}  // namespace

void parse_lod_level(const std::string& text, const std::string& option, LodSettings& lod) {
    if (text == "auto") {
        lod.automatic = true;
        lod.level = 0;
        return;
    }
    if (text.size() == 1 && text[0] >= '0' && text[0] <= char('0' + max_lod_level)) {
        lod.automatic = false;
        lod.level = text[0] - '0';
        return;
    }
    throw UsageError(fmt::format("{}: expected a level 0 to {} or \"auto\", got \"{}\"", option, max_lod_level, text));
}

std::string lod_simplifier() {
    return fmt::format("meshoptimizer {}.{} meshopt_simplify (lock border)", MESHOPTIMIZER_VERSION / 1000,
                       MESHOPTIMIZER_VERSION % 1000 / 10);
}

bool lod_keeps_group(const std::string& name) {
    const std::string n = lower(name);
    for (const char* part : {"lip", "teeth", "tooth", "tongue", "mouth", "inner", "cavity", "eye", "cornea", "iris",
                             "pupil", "lash", "brow", "lid"})
        if (n.find(part) != std::string::npos) return true;
    return false;
}

std::vector<char> lod_kept_triangles(const Head& head) {
    const auto& mesh = head.mesh;
    std::vector<char> vertex_kept(mesh.positions.size(), 0);
    for (const auto v : indexed_vertices(head)) vertex_kept[v] = 1;
    // What the eye channels move: the eyes and the lids.
    for (const auto& t : head.transforms) {
        if (t.channel_index < 0 || !is_eye_channel(static_cast<std::size_t>(t.channel_index))) continue;
        for (std::size_t j = 0; j < t.vertices.size(); ++j) {
            const bool moves = t.weights[j] > 0.01f && (t.offsets.empty() || glm::length(t.offsets[j]) > 1e-3f);
            if (moves) vertex_kept[t.vertices[j]] = 1;
        }
    }
    std::vector<char> group_kept(mesh.group_names.size(), 0);
    for (std::size_t g = 0; g < group_kept.size(); ++g) group_kept[g] = lod_keeps_group(mesh.group_names[g]) ? 1 : 0;
    std::vector<char> keep(mesh.triangle_count(), 0);
    auto mark = [&] {
        for (std::size_t t = 0; t < keep.size(); ++t)
            keep[t] = group_kept[static_cast<std::size_t>(mesh.triangle_group[t])] ||
                      vertex_kept[mesh.indices[3 * t]] || vertex_kept[mesh.indices[3 * t + 1]] ||
                      vertex_kept[mesh.indices[3 * t + 2]];
    };
    mark();
    // The margin: every vertex within lod_keep_margin_mm of a kept
    // triangle's vertex (the skin under the brows and lashes, round the eyes
    // and lips) is kept too.
    std::vector<char> source(mesh.positions.size(), 0);
    for (std::size_t t = 0; t < keep.size(); ++t)
        if (keep[t])
            for (int k = 0; k < 3; ++k) source[mesh.indices[3 * t + std::size_t(k)]] = 1;
    const auto near = near_vertices(mesh, source, lod_keep_margin_mm);
    for (std::size_t v = 0; v < near.size(); ++v) vertex_kept[v] = vertex_kept[v] || near[v];
    mark();
    return keep;
}

double lod_level_max_error_mm(int level) { return level <= 0 ? 0.0 : 0.25 * std::ldexp(1.0, level); }

LodResult head_at_level(const Head& head, int level) {
    if (level < 0 || level > max_lod_level)
        throw UsageError(fmt::format("level of detail: expected a level 0 to {}, got {}", max_lod_level, level));
    if (level == 0) return full_head(head);
    LodResult r = simplify(head, partition(head), std::ldexp(1.0, -level), lod_level_max_error_mm(level));
    r.chosen_by = "level";
    r.level = level;
    return r;
}

LodResult head_within_budget(const Head& head, std::size_t max_triangles) {
    if (max_triangles >= head.mesh.triangle_count()) {
        LodResult r = full_head(head);
        r.chosen_by = "max_triangles";
        return r;
    }
    // The finest level that fits.
    const Partition p = partition(head);
    LodResult r;
    for (int level = 1; level <= max_lod_level; ++level) {
        r = simplify(head, p, std::ldexp(1.0, -level), lod_level_max_error_mm(level));
        r.level = level;
        if (r.triangles <= max_triangles) {
            r.chosen_by = "max_triangles";
            return r;
        }
    }
    throw InputError(Diagnostic{
        head_file(head), 0, 0, "max_triangles",
        fmt::format("expected a budget of at least {} triangles for this head (its coarsest level, {}): its lips, "
                    "teeth and eyes stay at full detail ({} triangles) and the rest ({} triangles) simplifies to no "
                    "fewer than {} within {} mm; got {}",
                    r.triangles, max_lod_level, p.kept_count, p.rest_count, r.triangles - p.kept_count,
                    lod_level_max_error_mm(max_lod_level), max_triangles)});
}

LodResult automatic_lod(const Head& head, double pixels_per_mm, double max_error_px) {
    if (!(pixels_per_mm > 0.0) || !(max_error_px > 0.0))
        throw UsageError(fmt::format("automatic level of detail: expected positive pixels per mm and error, got {} "
                                     "and {}",
                                     pixels_per_mm, max_error_px));
    const Partition p = partition(head);
    LodResult r;
    for (int level = max_lod_level; level >= 1; --level) {
        r = simplify(head, p, std::ldexp(1.0, -level), lod_level_max_error_mm(level));
        if (r.error_mm * pixels_per_mm <= max_error_px) {
            r.level = level;
            break;
        }
    }
    if (r.level == 0) r = full_head(head);
    r.chosen_by = "auto";
    r.head_height_px = double(head.landmarks.head_height) * pixels_per_mm;
    return r;
}

LodResult level_of_detail(const Head& head, const LodSettings& lod, int height_px, double framing_mm) {
    const int given = int(lod.level != 0) + int(lod.max_triangles != 0) + int(lod.automatic);
    if (given > 1) throw UsageError("level of detail: give one of a level, a triangle budget and \"auto\"");
    if (lod.max_triangles != 0) return head_within_budget(head, lod.max_triangles);
    if (lod.automatic) {
        if (!(framing_mm > 0.0) || height_px <= 0)
            throw UsageError(fmt::format("automatic level of detail: expected a positive frame height and framing, got "
                                         "{} px and {} mm",
                                         height_px, framing_mm));
        return automatic_lod(head, double(height_px) / framing_mm, lod.max_error_px);
    }
    return head_at_level(head, lod.level);
}

}  // namespace avsi::stimuli
