// The head tool (head_builder.h): the built-in head from the MakeHuman
// assets. Steps: shape the base mesh (macro targets), fit the proxies, cut
// head, neck and shoulders, find the mouth's loops and regions, pack the
// textures into one atlas, bake the pose units into the rig's transforms,
// pick the landmarks, write OBJ + rig JSON + PNG. Everything is computed in
// a fixed order with fixed rounding so a rerun writes the same bytes.
#include "avsi/stimuli/head_builder.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <tuple>
#include <utility>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/stimuli/image_io.h"
#include "avsi/synth/parameters.h"
#include "makehuman.h"
#include "smoothstep.h"

namespace avsi::stimuli {

using namespace detail;
using nlohmann::json;

std::string head_variant_stem(HeadVariant variant) {
    switch (variant) {
        case HeadVariant::Male: return "head";
        case HeadVariant::Female: return "head-female";
        case HeadVariant::DarkMale: return "head-dark";
    }
    return "head";
}

HeadVariant head_variant_from_name(const std::string& name) {
    if (name == "male") return HeadVariant::Male;
    if (name == "female") return HeadVariant::Female;
    if (name == "dark-male") return HeadVariant::DarkMale;
    throw UsageError("--variant: expected male, female or dark-male, got \"" + name + "\"");
}

namespace {

constexpr float mm_per_unit = 100.0f;  // MakeHuman's units are decimetres

// Vertices of the hm08 base mesh's mouth (its topology is fixed; checked when used):
constexpr std::uint32_t upper_lip_edge_vertex = 474;   // the upper lip's lowest midline point, on the lip-line loop
constexpr std::uint32_t lower_lip_inner_vertex = 523;  // the lower lip's highest midline point, on the inner loop
constexpr std::uint32_t mouth_floor_vertex = 659;      // inside the mouth bag

// The cut: body faces wholly above this height (decimetres) and within this
// distance of the midline make head, neck and shoulders.
constexpr float cut_height = 4.3f;
constexpr float cut_half_width = 2.7f;
// A plain crew-neck shirt covers the body below the neck (a talker in the
// corpora is dressed): its neckline is the base mesh's edge loop round the
// neck through this front midline vertex; its colour (linear RGB).
constexpr std::uint32_t neckline_vertex = 1522;
constexpr std::uint32_t chest_vertex = 1526;  // below the neckline, on the chest
const glm::vec3 shirt_color{0.055f, 0.075f, 0.11f};

struct Variant {
    std::vector<std::pair<const char*, float>> targets;  // targets/ file, weight
    const char* skin;
    const char* brows;
    const char* label;
};

Variant variant_of(HeadVariant v) {
    switch (v) {
        case HeadVariant::Female:
            return {{{"universal-female-young-averagemuscle-averageweight.target", 1.0f},
                     {"caucasian-female-young.target", 1.0f},
                     {"female-young-averagemuscle-averageweight-idealproportions.target", 0.5f}},
                    "young_lightskinned_female_diffuse2.png", "eyebrow010", "female"};
        case HeadVariant::DarkMale:
            return {{{"universal-male-young-averagemuscle-averageweight.target", 1.0f},
                     {"african-male-young.target", 1.0f},
                     {"male-young-averagemuscle-averageweight-idealproportions.target", 0.5f}},
                    "young_darkskinned_male_diffuse.png", "eyebrow001", "dark-male"};
        case HeadVariant::Male:
        default:
            return {{{"universal-male-young-averagemuscle-averageweight.target", 1.0f},
                     {"caucasian-male-young.target", 1.0f},
                     {"male-young-averagemuscle-averageweight-idealproportions.target", 0.5f}},
                    "young_lightskinned_male_diffuse.png", "eyebrow001", "male"};
    }
}

// ---- Mesh topology of the base mesh's body ---------------------------------

struct Topology {
    std::vector<std::vector<std::uint32_t>> neighbours;  // sorted
    std::vector<std::vector<std::uint32_t>> faces_of;    // face indices per vertex
    const MhMesh* mesh = nullptr;

    Topology(const MhMesh& m, const std::vector<char>& use_face) : mesh(&m) {
        neighbours.resize(m.positions.size());
        faces_of.resize(m.positions.size());
        for (std::size_t f = 0; f < m.faces.size(); ++f) {
            if (!use_face[f]) continue;
            const auto& v = m.faces[f].v;
            for (std::size_t k = 0; k < v.size(); ++k) {
                const auto a = v[k], b = v[(k + 1) % v.size()];
                neighbours[a].push_back(b);
                neighbours[b].push_back(a);
                faces_of[a].push_back(static_cast<std::uint32_t>(f));
            }
        }
        for (auto& n : neighbours) {
            std::sort(n.begin(), n.end());
            n.erase(std::unique(n.begin(), n.end()), n.end());
        }
    }
    // Whether a face holds all of a, b and c.
    bool face_with(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
        for (auto f : faces_of[a]) {
            const auto& v = mesh->faces[f].v;
            if (std::find(v.begin(), v.end(), b) != v.end() && std::find(v.begin(), v.end(), c) != v.end()) return true;
        }
        return false;
    }
    // The closed edge loop through a → b (quads, valence-4 vertices), or empty.
    std::vector<std::uint32_t> loop(std::uint32_t a, std::uint32_t b) const {
        std::vector<std::uint32_t> out{a, b};
        for (int guard = 0; guard < 400; ++guard) {
            if (neighbours[b].size() != 4) return {};
            std::vector<std::uint32_t> next;
            for (auto c : neighbours[b])
                if (c != a && !face_with(a, b, c)) next.push_back(c);
            if (next.size() != 1) return {};
            a = b;
            b = next[0];
            if (b == out[0]) return out;
            out.push_back(b);
        }
        return {};
    }
};

// ---- Texture atlas ----------------------------------------------------------

struct AtlasRect {
    int source = 0;
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // source pixels
    int dx = 0, dy = 0, dw = 0, dh = 0;  // atlas pixels
};

struct AtlasSource {
    ImageRgba image;
    float scale = 1.0f;
    bool alpha = false;
};

struct Atlas {
    std::vector<AtlasSource> sources;
    std::vector<AtlasRect> rects;
    int width = 1024, height = 0;

    int add_source(ImageRgba image, float scale, bool alpha) {
        if (!alpha)
            for (std::size_t i = 3; i < image.rgba.size(); i += 4) image.rgba[i] = 255;
        sources.push_back({std::move(image), scale, alpha});
        return static_cast<int>(sources.size() - 1);
    }
    int add_rect(int source, int x0, int y0, int x1, int y1) {
        const auto& img = sources[static_cast<std::size_t>(source)].image;
        AtlasRect r;
        r.source = source;
        r.x0 = std::clamp(x0, 0, img.width);
        r.y0 = std::clamp(y0, 0, img.height);
        r.x1 = std::clamp(x1, r.x0 + 1, img.width);
        r.y1 = std::clamp(y1, r.y0 + 1, img.height);
        const float s = sources[static_cast<std::size_t>(source)].scale;
        r.dw = std::max(1, int(std::ceil(float(r.x1 - r.x0) * s)));
        r.dh = std::max(1, int(std::ceil(float(r.y1 - r.y0) * s)));
        rects.push_back(r);
        return static_cast<int>(rects.size() - 1);
    }
    // Shelf packing, tallest first (ties by index: a fixed order).
    void pack() {
        std::vector<std::size_t> order(rects.size());
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(), [&](auto a, auto b) { return rects[a].dh > rects[b].dh; });
        int x = 0, y = 0, shelf = 0;
        for (auto i : order) {
            auto& r = rects[i];
            if (r.dw > width) throw std::runtime_error("atlas: a texture region is wider than the atlas");
            if (x + r.dw > width) x = 0, y += shelf, shelf = 0;
            r.dx = x;
            r.dy = y;
            x += r.dw;
            shelf = std::max(shelf, r.dh);
        }
        height = (y + shelf + 3) / 4 * 4;
    }
    glm::vec2 map(int rect, glm::vec2 uv) const {
        const auto& r = rects[static_cast<std::size_t>(rect)];
        const auto& src = sources[static_cast<std::size_t>(r.source)];
        const float px = uv.x * float(src.image.width), py = (1.0f - uv.y) * float(src.image.height);
        const float ax = float(r.dx) + (px - float(r.x0)) * src.scale;
        const float ay = float(r.dy) + (py - float(r.y0)) * src.scale;
        return {ax / float(width), 1.0f - ay / float(height)};
    }
    // The atlas image: each rectangle resampled with a box filter of
    // bilinear samples; transparent texels of alpha sources take the
    // source's mean opaque colour (so filtering does not pull in a fringe).
    ImageRgba render() const {
        ImageRgba out;
        out.width = width;
        out.height = height;
        out.rgba.assign(std::size_t(width) * std::size_t(height) * 4, 0);
        std::vector<std::array<float, 3>> mean(sources.size(), {0, 0, 0});
        for (std::size_t s = 0; s < sources.size(); ++s) {
            if (!sources[s].alpha) continue;
            double sum[3] = {0, 0, 0}, w = 0;
            const auto& p = sources[s].image.rgba;
            for (std::size_t i = 0; i < p.size(); i += 4) {
                const double a = p[i + 3] / 255.0;
                for (int c = 0; c < 3; ++c) sum[c] += a * p[i + std::size_t(c)];
                w += a;
            }
            for (int c = 0; c < 3; ++c) mean[s][std::size_t(c)] = float(w > 0 ? sum[c] / w : 0.0);
        }
        for (const auto& r : rects) {
            const auto& src = sources[static_cast<std::size_t>(r.source)];
            const auto& img = src.image;
            auto texel = [&](int x, int y, int c) {
                x = std::clamp(x, 0, img.width - 1);
                y = std::clamp(y, 0, img.height - 1);
                const std::uint8_t* p = &img.rgba[(std::size_t(y) * std::size_t(img.width) + std::size_t(x)) * 4];
                if (c < 3 && src.alpha) {
                    const float a = p[3] / 255.0f;
                    return a * float(p[c]) + (1.0f - a) * mean[static_cast<std::size_t>(r.source)][std::size_t(c)];
                }
                return float(p[c]);
            };
            auto bilinear = [&](float x, float y, int c) {
                const float fx = std::floor(x - 0.5f), fy = std::floor(y - 0.5f);
                const float tx = x - 0.5f - fx, ty = y - 0.5f - fy;
                const int ix = int(fx), iy = int(fy);
                return (1 - ty) * ((1 - tx) * texel(ix, iy, c) + tx * texel(ix + 1, iy, c)) +
                       ty * ((1 - tx) * texel(ix, iy + 1, c) + tx * texel(ix + 1, iy + 1, c));
            };
            const int n = std::max(1, int(std::ceil(1.0f / src.scale)));
            for (int y = 0; y < r.dh; ++y)
                for (int x = 0; x < r.dw; ++x) {
                    float acc[4] = {0, 0, 0, 0};
                    for (int j = 0; j < n; ++j)
                        for (int i = 0; i < n; ++i) {
                            const float sx = float(r.x0) + (float(x) + (float(i) + 0.5f) / float(n)) / src.scale;
                            const float sy = float(r.y0) + (float(y) + (float(j) + 0.5f) / float(n)) / src.scale;
                            for (int c = 0; c < 4; ++c) acc[c] += bilinear(sx, sy, c);
                        }
                    std::uint8_t* o = &out.rgba[(std::size_t(r.dy + y) * std::size_t(width) + std::size_t(r.dx + x)) * 4];
                    for (int c = 0; c < 4; ++c)
                        o[c] = static_cast<std::uint8_t>(std::clamp(std::lround(acc[c] / float(n * n)), 0L, 255L));
                }
        }
        return out;
    }
};

// ---- The assembled head -----------------------------------------------------

// Where an output vertex comes from: a base vertex (proxy -1) or a proxy's.
struct OutVertex {
    int proxy = -1;
    std::uint32_t v = 0;
    glm::vec2 uv{0.0f};
    int part = 0;  // teeth: 1 upper row, 2 lower row (a vertex the proxy shares between rows is split)
};

struct Assembled {
    std::vector<OutVertex> vertices;
    std::vector<std::array<std::uint32_t, 3>> triangles;
    std::vector<std::string> triangle_group;
    std::map<std::pair<int, std::uint64_t>, std::uint32_t> index;  // (proxy, v << 32 | vt) → out
    std::map<std::pair<int, std::uint32_t>, std::uint32_t> first;  // (proxy, v) → first out vertex

    std::uint32_t vertex(int proxy, std::uint32_t v, std::uint32_t vt, glm::vec2 uv, int part = 0) {
        const auto key = std::make_pair(proxy * 4 + part, (std::uint64_t(v) << 32) | vt);
        const auto it = index.find(key);
        if (it != index.end()) return it->second;
        const auto i = static_cast<std::uint32_t>(vertices.size());
        vertices.push_back({proxy, v, uv, part});
        index[key] = i;
        first.emplace(std::make_pair(proxy, v), i);
        return i;
    }
    std::uint32_t of_base(std::uint32_t v) const {
        const auto it = first.find({-1, v});
        if (it == first.end()) throw std::runtime_error("head tool: base vertex " + std::to_string(v) + " is not in the head");
        return it->second;
    }
};

struct Proxy {
    MhProxy proxy;
    std::string group;  // or "" when the group comes per face (teeth)
    int atlas_rect = -1;
};

glm::mat3 scaled_rotation(const glm::mat3& r, float weight) {
    const glm::quat q = glm::quat_cast(r);
    const float angle = glm::angle(q);
    if (angle < 1e-7f) return glm::mat3(1.0f);
    return glm::mat3_cast(glm::angleAxis(angle * weight, glm::axis(q)));
}

// Rounds for the files to a step of 10^-k (k = 3 for 0.001): the nearest
// double to the decimal, so the JSON shows the short decimal.
double round_to(double x, double step) {
    const double inverse = std::round(1.0 / step);
    return std::round(x * inverse) / inverse + 0.0;
}

json vec3_json(glm::vec3 v, double step = 0.001) {
    return json::array({round_to(v.x, step), round_to(v.y, step), round_to(v.z, step)});
}

}  // namespace

namespace {

// What the head tool's steps share: the inputs, and what each step adds for
// the steps after it (in the order of build_head).
struct HeadBuild {
    const HeadBuildSettings& settings;
    const std::filesystem::path& dir;  // the MakeHuman assets
    Variant variant;

    // 1. shape_base_mesh
    MhMesh base;
    std::vector<glm::vec3> shaped;  // the base mesh's positions, shaped and with the lips closed
    MhSkeleton skeleton;
    std::vector<glm::mat4> rest;    // the bones' rest frames on the shaped mesh
    std::map<std::string, MhPose> units;
    // 2. add_proxies
    std::vector<Proxy> proxies;
    // 3. cut_head_and_mouth
    std::vector<char> body_face;
    std::optional<Topology> topo;
    std::vector<char> keep;                        // body faces of head, neck and shoulders
    std::vector<std::uint32_t> loop_a, loop_b;     // the lip line and the inner loop
    std::vector<char> cavity;                      // faces of the mouth bag
    std::set<std::uint32_t> on_loop_a, on_loop_b;
    std::vector<int> ring;                         // rings from the lip line, outside the mouth
    // 4. place_head_frame
    std::vector<std::vector<glm::vec3>> rest_proxies;
    glm::vec3 eye_left{0.0f}, eye_right{0.0f};     // the eyeballs' centres (base units)
    glm::vec3 origin{0.0f};
    // 5. assemble_mesh
    Atlas atlas;
    Assembled out;
    std::size_t n = 0;                 // output vertices
    std::vector<int> teeth_row;        // per output vertex: 1 upper teeth, 2 lower, 0 neither
    std::vector<glm::vec3> rest_pos;   // per output vertex, mm

    HeadBuild(const HeadBuildSettings& s, Variant v) : settings(s), dir(s.assets_dir), variant(std::move(v)) {}

    // A face pose unit by name.
    const MhPose& unit(const std::string& name) const {
        const auto it = units.find(name);
        if (it == units.end()) throw InputError(dir / "poses" / "face-poseunits.json", "no pose unit \"" + name + "\"");
        return it->second;
    }
    // A point of the base (or a proxy) in the head frame, mm.
    glm::vec3 to_mm(glm::vec3 p) const { return (p - origin) * mm_per_unit; }
    // A bone's joint in the head frame, mm.
    glm::vec3 pivot_of(const std::string& bone) const {
        return to_mm(glm::vec3(rest[static_cast<std::size_t>(skeleton.bone_index(bone))][3]));
    }
    // A base vertex's rest position in the output, mm.
    glm::vec3 P(std::uint32_t base_vertex) const { return rest_pos[out.of_base(base_vertex)]; }
};

// The proxies in the order they are added (the eyes first, the teeth fourth:
// teeth_proxy), their textures (nullptr: the proxy's name), atlas scales and
// whether their texture's alpha is kept.
constexpr int teeth_proxy = 3;
const char* const proxy_textures[] = {"brown_eye.png", nullptr, "eyelashes01.png", "teeth.png", "tongue01_diffuse.png",
                                      "short02_diffuse.png"};
const float proxy_scales[] = {0.25f, 0.5f, 0.5f, 0.25f, 0.25f, 0.25f};
const bool proxy_alpha[] = {true, true, true, false, false, true};

// Each base vertex's skinning weight in the bones of `root`'s subtree and in
// all bones: {in the subtree, total}.
std::pair<std::vector<float>, std::vector<float>> bone_subtree_weights(const MhSkeleton& skeleton, int root,
                                                                       std::size_t vertices) {
    std::vector<float> in(vertices, 0.0f), total(vertices, 0.0f);
    for (std::size_t b = 0; b < skeleton.bones.size(); ++b)
        for (const auto& [v, w] : skeleton.weights[b]) {
            if (v >= in.size()) continue;
            total[v] += w;
            if (skeleton.descends_from(int(b), root)) in[v] += w;
        }
    return {in, total};
}

// Step 1: the base mesh shaped by the variant's macro targets, the lips
// closed at rest, the skeleton's rest frames and the face pose units.
void shape_base_mesh(HeadBuild& h) {
    const auto& dir = h.dir;
    h.base = read_mh_obj(dir / "mesh" / "base.obj");
    auto& shaped = h.shaped;
    shaped = h.base.positions;
    for (const auto& [file, weight] : h.variant.targets)
        apply_target(read_target(dir / "targets" / file), weight, shaped);
    h.skeleton = read_skeleton(dir / "rig" / "default.mhskel", dir / "rig" / "default_weights.mhw");
    // The shape targets part the lips slightly; at rest they just meet: the
    // lower lip's bones' region is raised until the midline gap is 0.02 mm.
    const int lip = h.skeleton.bone_index("special04");
    if (lip < 0) throw InputError(dir / "rig" / "default.mhskel", "no bone \"special04\" (the lower lip's)");
    const auto [in, total] = bone_subtree_weights(h.skeleton, lip, shaped.size());
    const float gap = shaped[upper_lip_edge_vertex].y - shaped[lower_lip_inner_vertex].y - 0.02f / mm_per_unit;
    if (gap > 0)
        for (std::size_t v = 0; v < shaped.size(); ++v)
            if (total[v] > 0) shaped[v].y += gap * in[v] / total[v];
    h.rest = rest_frames(h.skeleton, shaped);
    h.units = read_pose_units(dir / "poses" / "face-poseunits.bvh", dir / "poses" / "face-poseunits.json");
}

// Step 2: the proxies (eyes, brows, lashes, teeth, tongue, hair) with their groups.
void add_proxies(HeadBuild& h) {
    auto add_proxy = [&](const std::string& name, const std::string& group) {
        h.proxies.push_back({read_mhclo(h.dir / "proxies" / (name + ".mhclo")), group, -1});
    };
    add_proxy("high-poly", "eyes");
    add_proxy(h.variant.brows, "brows");
    add_proxy("eyelashes01", "lashes");
    add_proxy("teeth_base", "");
    add_proxy("tongue01", "tongue");
    add_proxy("short02", "hair");
}

// The closed edge loop through base vertex v, walked toward the speaker's
// left along the neighbour most nearly level with v.
std::vector<std::uint32_t> loop_through(const HeadBuild& h, std::uint32_t v) {
    const auto& shaped = h.shaped;
    std::uint32_t side = v;
    for (auto n : h.topo->neighbours[v])
        if (shaped[n].x > shaped[v].x &&
            (side == v || std::abs(shaped[n].y - shaped[v].y) < std::abs(shaped[side].y - shaped[v].y)))
            side = n;
    auto l = h.topo->loop(v, side);
    if (l.size() < 8)
        throw InputError(h.dir / "mesh" / "base.obj",
                         "no closed edge loop through vertex " + std::to_string(v) + " (the hm08 base mesh has one there)");
    return l;
}

// The faces reached from the faces round `seed` (those `may_enter` allows)
// across shared edges, without crossing an edge of the closed loop
// `boundary` or entering a face `may_enter` refuses: 1 per reached face.
std::vector<char> flood_faces(const MhMesh& base, const Topology& topo, std::uint32_t seed,
                              const std::vector<std::uint32_t>& boundary,
                              const std::function<bool(std::uint32_t)>& may_enter) {
    std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
    for (std::size_t k = 0; k < boundary.size(); ++k) {
        const auto a = boundary[k], b = boundary[(k + 1) % boundary.size()];
        edges.insert({std::min(a, b), std::max(a, b)});
    }
    std::vector<char> reached(base.faces.size(), 0);
    std::vector<std::uint32_t> stack;
    for (auto f : topo.faces_of[seed])
        if (may_enter(f)) reached[f] = 1, stack.push_back(f);
    while (!stack.empty()) {
        const auto f = stack.back();
        stack.pop_back();
        const auto& v = base.faces[f].v;
        for (std::size_t k = 0; k < v.size(); ++k) {
            const auto a = v[k], b = v[(k + 1) % v.size()];
            if (edges.count({std::min(a, b), std::max(a, b)})) continue;
            for (auto g : topo.faces_of[a]) {
                if (reached[g] || !may_enter(g)) continue;
                const auto& w = base.faces[g].v;
                if (std::find(w.begin(), w.end(), b) == w.end()) continue;
                reached[g] = 1;
                stack.push_back(g);
            }
        }
    }
    return reached;
}

// Step 3: the faces of the body kept (head, neck and shoulders), the lip
// line (loop A: the upper lip's lower edge and the lower lip's front edge)
// and the inner loop (B), the mouth bag, and each vertex's ring from the lip
// line outside the mouth.
void cut_head_and_mouth(HeadBuild& h) {
    const auto& base = h.base;
    const auto& shaped = h.shaped;
    h.body_face.assign(base.faces.size(), 0);
    for (std::size_t f = 0; f < base.faces.size(); ++f)
        h.body_face[f] = base.group_names[static_cast<std::size_t>(base.faces[f].group)] == "body";
    h.topo.emplace(base, h.body_face);
    const Topology& topo = *h.topo;
    h.keep.assign(base.faces.size(), 0);
    for (std::size_t f = 0; f < base.faces.size(); ++f) {
        if (!h.body_face[f]) continue;
        bool inside = true;
        for (auto v : base.faces[f].v)
            inside = inside && shaped[v].y > cut_height && std::abs(shaped[v].x) < cut_half_width;
        h.keep[f] = inside;
    }
    h.loop_a = loop_through(h, upper_lip_edge_vertex);
    h.loop_b = loop_through(h, lower_lip_inner_vertex);
    // The mouth bag: faces reached from the mouth floor without crossing the lip line.
    h.cavity = flood_faces(base, topo, mouth_floor_vertex, h.loop_a, [](std::uint32_t) { return true; });
    h.on_loop_a = std::set<std::uint32_t>(h.loop_a.begin(), h.loop_a.end());
    h.on_loop_b = std::set<std::uint32_t>(h.loop_b.begin(), h.loop_b.end());
    // Lips: faces within a few rings of the lip line, outside the mouth.
    h.ring.assign(base.positions.size(), 1 << 20);
    std::vector<std::uint32_t> frontier(h.loop_a.begin(), h.loop_a.end());
    for (auto v : h.loop_a) h.ring[v] = 0;
    for (int r = 1; r <= 6; ++r) {
        std::vector<std::uint32_t> next;
        for (auto v : frontier)
            for (auto f : topo.faces_of[v]) {
                if (h.cavity[f]) continue;
                for (auto w : base.faces[f].v)
                    if (h.ring[w] > r) h.ring[w] = r, next.push_back(w);
            }
        frontier.swap(next);
    }
}

// The proxies fitted to base positions `b` (the shaped mesh or a posed one).
std::vector<std::vector<glm::vec3>> fitted_proxies(const HeadBuild& h, const std::vector<glm::vec3>& b) {
    std::vector<std::vector<glm::vec3>> out;
    for (const auto& p : h.proxies) out.push_back(fit_proxy(p.proxy, b));
    return out;
}

// Step 4: the proxies at rest and the head frame's origin: between the means
// of the eye proxy's two halves (the frame of the committed heads). Each
// eyeball's centre, its pivot: the middle of its bounding box (the vertices
// crowd at the back, so their mean lies about 5 mm in front of it).
void place_head_frame(HeadBuild& h) {
    h.rest_proxies = fitted_proxies(h, h.shaped);
    glm::vec3 eye_sum[2] = {glm::vec3(0.0f), glm::vec3(0.0f)};
    float eye_count[2] = {0, 0};
    glm::vec3 eye_lo[2] = {glm::vec3(1e9f), glm::vec3(1e9f)}, eye_hi[2] = {glm::vec3(-1e9f), glm::vec3(-1e9f)};
    for (const auto& p : h.rest_proxies[0]) {
        const int side = p.x > 0 ? 0 : 1;  // 0: the speaker's left (+x)
        eye_sum[side] += p;
        eye_count[side] += 1;
        eye_lo[side] = glm::min(eye_lo[side], p);
        eye_hi[side] = glm::max(eye_hi[side], p);
    }
    if (eye_count[0] == 0 || eye_count[1] == 0)
        throw InputError(h.dir / "proxies" / "high-poly.mhclo", "expected two eyes");
    const glm::vec3 eye_mean_left = eye_sum[0] / eye_count[0], eye_mean_right = eye_sum[1] / eye_count[1];
    h.eye_left = 0.5f * (eye_lo[0] + eye_hi[0]);
    h.eye_right = 0.5f * (eye_lo[1] + eye_hi[1]);
    h.origin = glm::vec3(0.0f, 0.5f * (eye_mean_left.y + eye_mean_right.y), 0.5f * (eye_mean_left.z + eye_mean_right.z));
}

// The skin's UV islands among the kept and mouth faces, one atlas rectangle
// each: the rectangle of each of the base mesh's texture coordinates (-1 for
// those of faces left out).
std::vector<int> skin_islands(HeadBuild& h, int skin_source, const ImageRgba& skin_image) {
    const auto& base = h.base;
    std::vector<int> island_of_vt(base.uvs.size(), -1);
    std::vector<std::uint32_t> parent(base.uvs.size());
    std::iota(parent.begin(), parent.end(), 0u);
    std::function<std::uint32_t(std::uint32_t)> find = [&](std::uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    for (std::size_t f = 0; f < base.faces.size(); ++f) {
        if (!h.keep[f] && !h.cavity[f]) continue;
        const auto& vt = base.faces[f].vt;
        if (vt.empty()) throw InputError(h.dir / "mesh" / "base.obj", "a face of the body has no texture coordinates");
        for (std::size_t k = 1; k < vt.size(); ++k) parent[find(vt[k])] = find(vt[0]);
    }
    std::map<std::uint32_t, std::array<float, 4>> box;  // root → u0 v0 u1 v1
    for (std::size_t f = 0; f < base.faces.size(); ++f) {
        if (!h.keep[f] && !h.cavity[f]) continue;
        for (auto t : base.faces[f].vt) {
            auto [it, fresh] = box.try_emplace(find(t), std::array<float, 4>{1e9f, 1e9f, -1e9f, -1e9f});
            auto& b = it->second;
            b[0] = std::min(b[0], base.uvs[t].x), b[1] = std::min(b[1], base.uvs[t].y);
            b[2] = std::max(b[2], base.uvs[t].x), b[3] = std::max(b[3], base.uvs[t].y);
        }
    }
    std::map<std::uint32_t, int> rect_of_root;
    const int pad = 8;
    for (const auto& [root, b] : box) {
        const float w = float(skin_image.width), ht = float(skin_image.height);
        rect_of_root[root] = h.atlas.add_rect(skin_source, int(std::floor(b[0] * w)) - pad,
                                              int(std::floor((1.0f - b[3]) * ht)) - pad, int(std::ceil(b[2] * w)) + pad,
                                              int(std::ceil((1.0f - b[1]) * ht)) + pad);
    }
    for (std::size_t t = 0; t < base.uvs.size(); ++t)
        if (box.count(find(static_cast<std::uint32_t>(t)))) island_of_vt[t] = rect_of_root[find(static_cast<std::uint32_t>(t))];
    return island_of_vt;
}

// The atlas laid out: the skin's islands (island_of_vt), each proxy's
// texture, and a white patch the shirt samples (its colour is the vertex
// colour), packed; returns the white patch's texture coordinate.
glm::vec2 pack_atlas(HeadBuild& h, std::vector<int>& island_of_vt) {
    const ImageRgba skin_image = read_image_rgba(h.dir / "textures" / h.variant.skin);
    const int skin_source = h.atlas.add_source(skin_image, h.settings.skin_texture_scale, false);
    island_of_vt = skin_islands(h, skin_source, skin_image);
    for (std::size_t p = 0; p < h.proxies.size(); ++p) {
        const char* file = proxy_textures[p] ? proxy_textures[p] : nullptr;
        const std::string name = file ? std::string(file) : h.proxies[p].proxy.name + ".png";
        const ImageRgba img = read_image_rgba(h.dir / "textures" / name);
        const int s = h.atlas.add_source(img, proxy_scales[p], proxy_alpha[p]);
        h.proxies[p].atlas_rect = h.atlas.add_rect(s, 0, 0, img.width, img.height);
    }
    ImageRgba white;
    white.width = white.height = 8;
    white.rgba.assign(8 * 8 * 4, 255);
    const int white_rect = h.atlas.add_rect(h.atlas.add_source(white, 1.0f, false), 0, 0, 8, 8);
    h.atlas.pack();
    return h.atlas.map(white_rect, glm::vec2(0.5f, 0.5f));
}

// Each base vertex's hop distance to the lip line's upper and lower arcs
// (loop A split at its corners): {to the upper arc, to the lower arc}.
std::pair<std::vector<int>, std::vector<int>> lip_arc_hops(const HeadBuild& h) {
    const auto& loop_a = h.loop_a;
    const auto& shaped = h.shaped;
    std::vector<int> hops_upper(h.base.positions.size(), 1 << 20), hops_lower(h.base.positions.size(), 1 << 20);
    std::size_t left = 0, right = 0;
    for (std::size_t k = 0; k < loop_a.size(); ++k) {
        if (shaped[loop_a[k]].x > shaped[loop_a[left]].x) left = k;
        if (shaped[loop_a[k]].x < shaped[loop_a[right]].x) right = k;
    }
    const bool upper_first = [&] {
        for (std::size_t k = (left + 1) % loop_a.size(); k != right; k = (k + 1) % loop_a.size())
            if (loop_a[k] == upper_lip_edge_vertex) return true;
        return false;
    }();
    for (int side = 0; side < 2; ++side) {
        auto& hops = side == 0 ? hops_upper : hops_lower;
        std::vector<std::uint32_t> frontier;
        const bool first_arc = (side == 0) == upper_first;
        const std::size_t from = first_arc ? left : right, to = first_arc ? right : left;
        for (std::size_t k = (from + 1) % loop_a.size(); k != to; k = (k + 1) % loop_a.size()) {
            hops[loop_a[k]] = 0;
            frontier.push_back(loop_a[k]);
        }
        for (int hop = 1; !frontier.empty() && hop < 400; ++hop) {
            std::vector<std::uint32_t> next;
            for (auto v : frontier)
                for (auto w : h.topo->neighbours[v])
                    if (hops[w] > hop) hops[w] = hop, next.push_back(w);
            frontier.swap(next);
        }
    }
    return {hops_upper, hops_lower};
}

// Appends a face's fan of triangles (corners in order) to the output in `group`.
void add_fan(Assembled& out, const std::vector<std::uint32_t>& corners, const std::string& group) {
    for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
        out.triangles.push_back({corners[0], corners[k], corners[k + 1]});
        out.triangle_group.push_back(group);
    }
}

// The kept body faces and the mouth in the output mesh, split at UV seams,
// each in its group: the shirt (the kept faces reached from the chest
// without crossing the neckline loop), the skin, the lips and their inner
// surfaces and the mouth's cavity, upper or lower by the hop distance to
// the lip line's arcs, ties by whether JawDrop moves the face.
void add_body_faces(HeadBuild& h, const std::vector<int>& island_of_vt, glm::vec2 white_uv) {
    const auto& base = h.base;
    const auto& shaped = h.shaped;
    const auto& cavity = h.cavity;
    const auto& keep = h.keep;
    const std::vector<char> shirt_face = flood_faces(base, *h.topo, chest_vertex, loop_through(h, neckline_vertex),
                                                     [&](std::uint32_t g) { return keep[g] && !cavity[g]; });
    // JawDrop at full weight tells the lower jaw's parts from the upper ones.
    const auto jaw_drop_base = skin(h.skeleton, skinning_matrices(h.skeleton, h.rest, h.unit("JawDrop")), shaped);
    const auto [hops_upper, hops_lower] = lip_arc_hops(h);
    auto lower_part = [&](const std::vector<std::uint32_t>& v) {
        int up = 0, low = 0;
        float dy = 0;
        for (auto i : v) up += hops_upper[i], low += hops_lower[i], dy += jaw_drop_base[i].y - shaped[i].y;
        if (up != low) return low < up;
        return dy / float(v.size()) * mm_per_unit < -4.0f;
    };
    for (std::size_t f = 0; f < base.faces.size(); ++f) {
        if (!keep[f] && !cavity[f]) continue;
        const auto& face = base.faces[f];
        std::string group = "skin";
        const bool lower = lower_part(face.v);
        if (shirt_face[f] != 0) {
            std::vector<std::uint32_t> corners;
            for (std::size_t k = 0; k < face.v.size(); ++k) corners.push_back(h.out.vertex(-1, face.v[k], 0, white_uv, 3));
            add_fan(h.out, corners, "shirt");
            continue;
        }
        if (cavity[f]) {
            // The lips' inner surfaces: the faces on either of the two loops.
            bool band = false;
            for (auto v : face.v) band = band || h.on_loop_a.count(v) || h.on_loop_b.count(v);
            group = std::string(lower ? "lower" : "upper") + (band ? "_inner" : "_cavity");
        } else {
            int far = 0;
            for (auto v : face.v) far = std::max(far, h.ring[v]);
            if (far <= 4) group = lower ? "lower_lip" : "upper_lip";
        }
        std::vector<std::uint32_t> corners;
        for (std::size_t k = 0; k < face.v.size(); ++k)
            corners.push_back(h.out.vertex(-1, face.v[k], face.vt[k],
                                           h.atlas.map(island_of_vt[face.vt[k]], base.uvs[face.vt[k]])));
        add_fan(h.out, corners, group);
    }
}

// The proxies' faces in the output mesh, each in its proxy's group; the eye's
// transparent shell is the cornea, and each tooth is upper or lower by the
// helper it follows.
void add_proxy_faces(HeadBuild& h) {
    const auto& base = h.base;
    std::set<std::uint32_t> upper_teeth_helper;
    for (const auto& f : base.faces)
        if (base.group_names[static_cast<std::size_t>(f.group)] == "helper-upper-teeth")
            upper_teeth_helper.insert(f.v.begin(), f.v.end());
    for (std::size_t p = 0; p < h.proxies.size(); ++p) {
        const auto& m = h.proxies[p].proxy.mesh;
        for (const auto& face : m.faces) {
            if (face.vt.size() != face.v.size())
                throw InputError(h.dir / "proxies" / (h.proxies[p].proxy.name + ".obj"), "a face has no texture coordinates");
            std::string group = h.proxies[p].group;
            if (group == "eyes") {
                // The eye's transparent shell (its texels have no alpha) is the cornea.
                const auto& img = h.atlas.sources[static_cast<std::size_t>(h.atlas.rects[static_cast<std::size_t>(h.proxies[p].atlas_rect)].source)].image;
                glm::vec2 c(0.0f);
                for (auto t : face.vt) c += m.uvs[t];
                c /= float(face.vt.size());
                const int x = std::clamp(int(c.x * float(img.width)), 0, img.width - 1);
                const int y = std::clamp(int((1.0f - c.y) * float(img.height)), 0, img.height - 1);
                if (img.rgba[(std::size_t(y) * std::size_t(img.width) + std::size_t(x)) * 4 + 3] < 128) group = "cornea";
            }
            if (group.empty())
                group = upper_teeth_helper.count(h.proxies[p].proxy.refs[face.v[0]][0]) ? "upper_teeth" : "lower_teeth";
            std::vector<std::uint32_t> corners;
            for (std::size_t k = 0; k < face.v.size(); ++k)
                corners.push_back(h.out.vertex(int(p), face.v[k], face.vt[k], h.atlas.map(h.proxies[p].atlas_rect, m.uvs[face.vt[k]]),
                                               group == "upper_teeth" ? 1 : group == "lower_teeth" ? 2 : 0));
            add_fan(h.out, corners, group);
        }
    }
}

// The output vertices' positions (mm) for base positions `b`. The teeth
// proxy sits high and deep behind the lips of these shapes: the upper
// incisal edge 5 mm above the lip line and 10 mm behind it. Both rows move
// forward and the upper one down, so the upper incisors' edge sits about
// 2 mm above the lip line as in a young adult at rest.
std::vector<glm::vec3> output_positions(const HeadBuild& h, const std::vector<glm::vec3>& b) {
    const glm::vec3 upper_teeth_shift(0.0f, -3.0f, 3.5f), lower_teeth_shift(0.0f, -1.5f, 2.5f);
    const auto px = fitted_proxies(h, b);
    std::vector<glm::vec3> pos(h.n);
    for (std::size_t i = 0; i < h.n; ++i) {
        const auto& o = h.out.vertices[i];
        pos[i] = h.to_mm(o.proxy < 0 ? b[o.v] : px[static_cast<std::size_t>(o.proxy)][o.v]);
        if (o.proxy == teeth_proxy) pos[i] += h.teeth_row[i] == 1 ? upper_teeth_shift : lower_teeth_shift;
    }
    return pos;
}

// Step 5: the output mesh (the kept body faces and the proxies, split at UV
// seams, their textures packed into one atlas) and its rest positions. The
// teeth are rigid: the upper row stays with the skull, the lower row follows
// the jaw bone only (the skinning spreads lip bones' weights onto the teeth
// helpers).
void assemble_mesh(HeadBuild& h) {
    std::vector<int> island_of_vt;
    const glm::vec2 white_uv = pack_atlas(h, island_of_vt);
    add_body_faces(h, island_of_vt, white_uv);
    add_proxy_faces(h);
    h.n = h.out.vertices.size();
    h.teeth_row.assign(h.n, 0);
    for (std::size_t i = 0; i < h.n; ++i) h.teeth_row[i] = h.out.vertices[i].part;
    h.rest_pos = output_positions(h, h.shaped);
}

// A pose of several units, each at its weight.
MhPose pose_of(const HeadBuild& h, std::initializer_list<std::pair<const char*, float>> parts) {
    MhPose pose;
    for (const auto& [name, weight] : parts)
        for (const auto& [bone, r] : h.unit(name)) {
            const glm::mat3 s = scaled_rotation(r, weight);
            const auto it = pose.find(bone);
            pose[bone] = it == pose.end() ? s : s * it->second;
        }
    return pose;
}

// Each output vertex's displacement (mm) in a pose; the upper teeth never
// move, the lower teeth only when the pose turns the jaw.
std::vector<glm::vec3> pose_displacement(const HeadBuild& h, const MhPose& pose) {
    auto pos = output_positions(h, skin(h.skeleton, skinning_matrices(h.skeleton, h.rest, pose), h.shaped));
    for (std::size_t i = 0; i < h.n; ++i) pos[i] -= h.rest_pos[i];
    const bool jaw_moves = pose.count("jaw") > 0;
    for (std::size_t i = 0; i < h.n; ++i)
        if (h.teeth_row[i] == 1 || (h.teeth_row[i] == 2 && !jaw_moves)) pos[i] = glm::vec3(0.0f);
    return pos;
}

// A bone subtree's share of each output vertex's skinning weights.
std::vector<float> subtree_weight(const HeadBuild& h, const std::string& bone) {
    const int root = h.skeleton.bone_index(bone);
    if (root < 0) throw InputError(h.dir / "rig" / "default.mhskel", "no bone \"" + bone + "\"");
    const auto [in, total] = bone_subtree_weights(h.skeleton, root, h.base.positions.size());
    std::vector<float> share(h.base.positions.size());
    for (std::size_t v = 0; v < share.size(); ++v) share[v] = total[v] > 0 ? in[v] / total[v] : 0.0f;
    std::vector<float> w(h.n);
    for (std::size_t i = 0; i < h.n; ++i) {
        const auto& o = h.out.vertices[i];
        if (o.proxy < 0) {
            w[i] = share[o.v];
        } else {
            const auto& pr = h.proxies[static_cast<std::size_t>(o.proxy)].proxy;
            const auto& r = pr.refs[o.v];
            const auto& rw = pr.ref_weights[o.v];
            w[i] = std::clamp(rw.x * share[r[0]] + rw.y * share[r[1]] + rw.z * share[r[2]], 0.0f, 1.0f);
        }
    }
    return w;
}

// The articulation landmarks and the face's measures (output vertices and mm).
struct HeadLandmarks {
    std::uint32_t corner_left = 0, corner_right = 0;  // base vertices: loop A's outermost points
    std::vector<std::uint32_t> upper_contour, lower_contour;
    std::uint32_t upper_point = 0, lower_point = 0;
    std::vector<std::uint32_t> upper_incisors, lower_incisors;
    std::vector<std::uint32_t> lip_surface;
    glm::vec3 mouth_middle{0.0f};
    glm::vec3 nose_bottom{0.0f, 0.0f, -1e9f}, chin{0.0f, 1e9f, 0.0f};
    float crown = -1e9f;
    float iris = 0;
};

// The half of a loop from its left corner to its right (its outermost
// points) that contains `through`, and the two corners.
std::tuple<std::vector<std::uint32_t>, std::uint32_t, std::uint32_t> loop_half(
    const HeadBuild& h, const std::vector<std::uint32_t>& loop, std::uint32_t through) {
    const auto& shaped = h.shaped;
    std::size_t left = 0, right = 0;
    for (std::size_t k = 0; k < loop.size(); ++k) {
        if (shaped[loop[k]].x > shaped[loop[left]].x) left = k;
        if (shaped[loop[k]].x < shaped[loop[right]].x) right = k;
    }
    // The arc from left to right that contains `through`.
    std::vector<std::uint32_t> arc1, arc2;
    for (std::size_t k = (left + 1) % loop.size(); k != right; k = (k + 1) % loop.size()) arc1.push_back(loop[k]);
    for (std::size_t k = (right + 1) % loop.size(); k != left; k = (k + 1) % loop.size()) arc2.push_back(loop[k]);
    const bool first = std::find(arc1.begin(), arc1.end(), through) != arc1.end();
    return std::make_tuple(first ? arc1 : arc2, loop[left], loop[right]);
}

// The inner-lip contours: loop A's upper half (corner to corner through the
// upper lip's edge) against loop B's lower half, paired by x.
void lip_contours(const HeadBuild& h, HeadLandmarks& l) {
    const auto& shaped = h.shaped;
    const auto [upper_arc, corner_left, corner_right] = loop_half(h, h.loop_a, upper_lip_edge_vertex);
    const auto lower_arc = std::get<0>(loop_half(h, h.loop_b, lower_lip_inner_vertex));
    l.corner_left = corner_left;
    l.corner_right = corner_right;
    std::set<std::uint32_t> used;
    for (auto v : lower_arc) {
        std::uint32_t best = upper_arc[0];
        for (auto u : upper_arc)
            if (std::abs(shaped[u].x - shaped[v].x) < std::abs(shaped[best].x - shaped[v].x)) best = u;
        // Distinct points; pairs near the corners whose edges already meet at rest measure nothing.
        if (!used.insert(best).second || (shaped[best].y - shaped[v].y) * mm_per_unit < 0.05f) continue;
        l.upper_contour.push_back(h.out.of_base(best));
        l.lower_contour.push_back(h.out.of_base(v));
    }
}

// The most forward midline point of a group.
std::uint32_t front_midline(const HeadBuild& h, const char* group) {
    std::uint32_t best = 0;
    float z = -1e9f;
    for (std::size_t t = 0; t < h.out.triangles.size(); ++t) {
        if (h.out.triangle_group[t] != group) continue;
        for (auto i : h.out.triangles[t])
            if (std::abs(h.rest_pos[i].x) < 0.05f && h.rest_pos[i].z > z) z = h.rest_pos[i].z, best = i;
    }
    return best;
}

// An incisal edge: the front teeth's lowest (upper) or highest (lower)
// front points across the central 16 mm, in 2 mm steps.
std::vector<std::uint32_t> incisal_edge(const HeadBuild& h, const char* group, bool lowest) {
    float z_front = -1e9f;
    std::set<std::uint32_t> verts;
    for (std::size_t t = 0; t < h.out.triangles.size(); ++t)
        if (h.out.triangle_group[t] == group) verts.insert(h.out.triangles[t].begin(), h.out.triangles[t].end());
    for (auto i : verts) z_front = std::max(z_front, h.rest_pos[i].z);
    std::vector<std::uint32_t> edge;
    for (float x = -8.0f; x <= 8.01f; x += 2.0f) {
        std::uint32_t best = 0;
        float y = lowest ? 1e9f : -1e9f;
        bool found = false;
        for (auto i : verts) {
            const auto& p = h.rest_pos[i];
            if (std::abs(p.x - x) > 1.0f || p.z < z_front - 4.0f) continue;
            if (lowest ? p.y < y : p.y > y) y = p.y, best = i, found = true;
        }
        if (found && (edge.empty() || edge.back() != best)) edge.push_back(best);
    }
    if (edge.size() < 2) throw std::runtime_error(std::string("head tool: no incisal edge found on the ") + group);
    return edge;
}

// The lower lip's upper surface: its inner band and the outer rows next to
// the lip line, across the central 24 mm.
std::vector<std::uint32_t> pick_lower_lip_surface(const HeadBuild& h) {
    std::set<std::uint32_t> s;
    for (std::size_t t = 0; t < h.out.triangles.size(); ++t) {
        const auto& g = h.out.triangle_group[t];
        if (g != "lower_inner" && g != "lower_lip") continue;
        for (auto i : h.out.triangles[t]) {
            const auto& o = h.out.vertices[i];
            if (o.proxy >= 0 || std::abs(h.rest_pos[i].x) > 12.0f) continue;
            if (g == "lower_lip" && h.ring[o.v] > 4) continue;
            if (h.out.first.at({-1, o.v}) == i) s.insert(i);
        }
    }
    return std::vector<std::uint32_t>(s.begin(), s.end());
}

// The midline profile: subnasale (the deepest midline skin point between the
// lip and the nose tip), the chin, and the crown's height.
void midline_profile(const HeadBuild& h, HeadLandmarks& l) {
    const glm::vec3& mouth_middle = l.mouth_middle;
    for (std::size_t i = 0; i < h.n; ++i) {
        const auto& o = h.out.vertices[i];
        const auto& p = h.rest_pos[i];
        l.crown = std::max(l.crown, p.y);
        if (o.proxy >= 0 || std::abs(p.x) > 0.05f) continue;
        if (p.y > mouth_middle.y + 8.0f && p.y < mouth_middle.y + 30.0f && p.z > mouth_middle.z - 12.0f &&
            (l.nose_bottom.z < -1e8f || p.z < l.nose_bottom.z))
            l.nose_bottom = p;
        if (p.z > mouth_middle.z - 25.0f && p.y < l.chin.y && p.y > mouth_middle.y - 70.0f) l.chin = p;
    }
}

// The iris: the width of the left eye's dark (iris-textured) front, mm.
float iris_width(const HeadBuild& h) {
    const Proxy& eyes = h.proxies[0];
    const auto& img = h.atlas.sources[static_cast<std::size_t>(h.atlas.rects[static_cast<std::size_t>(eyes.atlas_rect)].source)].image;
    float lo = 1e9f, hi = -1e9f;
    for (const auto& face : eyes.proxy.mesh.faces)
        for (std::size_t k = 0; k < face.v.size(); ++k) {
            const glm::vec3 p = h.to_mm(h.rest_proxies[0][face.v[k]]);
            if (p.x <= 0) continue;
            const glm::vec2 uv = eyes.proxy.mesh.uvs[face.vt[k]];
            const int x = std::clamp(int(uv.x * float(img.width)), 0, img.width - 1);
            const int y = std::clamp(int((1.0f - uv.y) * float(img.height)), 0, img.height - 1);
            const std::uint8_t* c = &img.rgba[(std::size_t(y) * std::size_t(img.width) + std::size_t(x)) * 4];
            if (c[3] < 128 || 0.3f * c[0] + 0.59f * c[1] + 0.11f * c[2] > 110.0f) continue;  // sclera or shell
            lo = std::min(lo, p.x), hi = std::max(hi, p.x);
        }
    return hi > lo ? hi - lo : 0.0f;
}

// Step 6: the landmarks (mm) picked from the mesh around the mouth, the teeth and the eyes.
HeadLandmarks pick_landmarks(const HeadBuild& h) {
    HeadLandmarks l;
    lip_contours(h, l);
    l.upper_point = front_midline(h, "upper_lip");
    l.lower_point = front_midline(h, "lower_lip");
    l.upper_incisors = incisal_edge(h, "upper_teeth", true);
    l.lower_incisors = incisal_edge(h, "lower_teeth", false);
    l.lip_surface = pick_lower_lip_surface(h);
    l.mouth_middle = 0.5f * (h.P(upper_lip_edge_vertex) + h.P(lower_lip_inner_vertex));
    midline_profile(h, l);
    l.iris = iris_width(h);
    return l;
}

// The rig's transforms as they are made: the masks that keep each kind of
// channel to its part of the face, and the transforms so far, one JSON
// object each in the rig's order.
class RigTransforms {
public:
    // The speech channels move the lower face only: the units' small
    // motions above the cheekbones (temples, under the hair and brows) fade
    // out between 40 and 25 mm below the eyes; eyes, brows, lashes and hair
    // keep still. Static hair and brows then stay static for the renderer.
    // They also fade out beyond the jaw (an ellipsoid round the mouth and
    // chin): the neck and shoulders keep still, so the renderer redraws only
    // the lower face each frame. The expression channels (brows, cheeks)
    // move the upper face only: they fade out round the lips (an ellipsoid
    // about the mouth), so no expression can open a lip closure; the
    // eyeballs, teeth and tongue keep still.
    explicit RigTransforms(const HeadBuild& h) : m_h(h), m_speech_mask(h.n, 1.0f), m_expression_mask(h.n, 1.0f) {
        const glm::vec3 mouth_rest = 0.5f * (h.P(upper_lip_edge_vertex) + h.P(lower_lip_inner_vertex));
        const glm::vec3 jaw_centre = mouth_rest - glm::vec3(0.0f, 20.0f, 25.0f), jaw_radii(72.0f, 62.0f, 85.0f);
        for (std::size_t i = 0; i < h.n; ++i) {
            const int proxy = h.out.vertices[i].proxy;
            const float reach = glm::length((h.rest_pos[i] - jaw_centre) / jaw_radii);
            m_speech_mask[i] =
                proxy >= 0 && proxy != teeth_proxy && h.proxies[static_cast<std::size_t>(proxy)].group != "tongue"
                    ? 0.0f
                    : (1.0f - smoothstep(-40.0f, -25.0f, h.rest_pos[i].y)) * (1.0f - smoothstep(0.75f, 1.0f, reach));
        }
        const glm::vec3 lips_radii(34.0f, 16.0f, 30.0f);
        for (std::size_t i = 0; i < h.n; ++i) {
            const int proxy = h.out.vertices[i].proxy;
            const float reach = glm::length((h.rest_pos[i] - mouth_rest) / lips_radii);
            const bool still = proxy == 0 || proxy == teeth_proxy ||
                               (proxy > 0 && h.proxies[static_cast<std::size_t>(proxy)].group == "tongue");
            m_expression_mask[i] = still ? 0.0f : smoothstep(1.0f, 1.5f, reach);
        }
    }

    // A displacement per unit of the channel (of its `side`, or both when
    // null), masked by the channel's kind; offsets under 0.05 mm are left out.
    void blendshape(const std::string& channel, const std::vector<glm::vec3>& d, float per_unit, const char* side,
                    const std::string& note) {
        json vertices = json::array(), offsets = json::array();
        const bool expression = is_expression(channel);
        const bool speech = channel != "blink" && channel.rfind("gaze", 0) != 0 && !expression;
        for (std::size_t i = 0; i < m_h.n; ++i) {
            const glm::vec3 o =
                d[i] * per_unit * (speech ? m_speech_mask[i] : expression ? m_expression_mask[i] : 1.0f);
            if (glm::length(o) < keep_offset_mm) continue;
            vertices.push_back(i);
            for (int c = 0; c < 3; ++c) offsets.push_back(round_to(o[c], offset_step));
        }
        json t = {{"channel", channel}, {"note", note}, {"blendshape", {{"vertices", vertices}, {"offsets", offsets}}}};
        if (side) t["side"] = side;
        m_transforms.push_back(t);
    }

    // A bone's rotation in a unit as a weighted rotation transform, and the
    // rest of the unit's motion as a blendshape on the same channel.
    void rotation_and_rest(const std::string& channel, const std::string& unit_name, const std::string& bone,
                           float per_unit, const std::string& note) {
        const HeadBuild& h = m_h;
        const std::size_t n = h.n;
        const MhPose& pose = h.unit(unit_name);
        const glm::quat q = glm::quat_cast(pose.at(bone));
        const float angle = glm::degrees(glm::angle(q));
        const glm::vec3 axis = glm::axis(q);
        glm::vec3 pivot = h.pivot_of(bone);
        auto weights = subtree_weight(h, bone);
        auto d = pose_displacement(h, pose);
        if (bone == "eye.L" || bone == "eye.R") {
            // An eyeball turns about its own centre (the bone's head lies
            // 8 mm behind the proxy's), rigidly: no rest for its vertices.
            pivot = h.to_mm(bone == "eye.L" ? h.eye_left : h.eye_right);
            for (std::size_t i = 0; i < n; ++i)
                if (h.out.vertices[i].proxy == 0) {
                    const bool same_side = (h.rest_pos[i].x > 0) == (bone == "eye.L");
                    weights[i] = same_side ? 1.0f : 0.0f;
                    const glm::quat r = glm::angleAxis(glm::radians(angle) * weights[i], axis);
                    d[i] = (pivot + r * (h.rest_pos[i] - pivot)) - h.rest_pos[i];
                }
        }
        if (bone == "jaw")
            for (std::size_t i = 0; i < n; ++i)
                if (h.teeth_row[i] != 0) {
                    weights[i] = h.teeth_row[i] == 2 ? 1.0f : 0.0f;
                    // The lower row turns with the jaw and nothing else.
                    const glm::quat r = glm::angleAxis(glm::angle(glm::quat_cast(pose.at(bone))) * weights[i],
                                                       glm::axis(glm::quat_cast(pose.at(bone))));
                    d[i] = h.teeth_row[i] == 2 ? (h.pivot_of(bone) + r * (h.rest_pos[i] - h.pivot_of(bone))) - h.rest_pos[i]
                                               : glm::vec3(0.0f);
                }
        json vertices = json::array(), w = json::array();
        for (std::size_t i = 0; i < n; ++i) {
            const bool speech = channel != "blink" && channel.rfind("gaze", 0) != 0;
            const float wi = float(round_to(weights[i] * (speech ? m_speech_mask[i] : 1.0f), 0.0001));
            if (wi <= 0.0f) continue;
            vertices.push_back(i);
            w.push_back(wi);
            const glm::quat r = glm::angleAxis(glm::radians(angle) * wi, axis);
            d[i] -= (pivot + r * (h.rest_pos[i] - pivot)) - h.rest_pos[i];
        }
        m_transforms.push_back({{"channel", channel},
                                {"note", note},
                                {"rotate",
                                 {{"pivot", vec3_json(pivot)},
                                  {"axis", vec3_json(axis, 1e-6)},
                                  {"angle_deg", round_to(angle * per_unit, 1e-4)}}},
                                {"weights", {{"vertices", vertices}, {"values", w}}}});
        // The eye units' other bones (lids, brows and the skin round the
        // orbit) are left out: moved by the gaze, the skin under the brows
        // left the static part and was drawn over the blended brows.
        if (bone != "eye.L" && bone != "eye.R")
            blendshape(channel, d, per_unit, nullptr, note + " (the unit's other bones)");
    }

    const json& transforms() const { return m_transforms; }

private:
    static constexpr double offset_step = 0.001;  // mm
    static constexpr float keep_offset_mm = 0.05f;
    static bool is_expression(const std::string& channel) {
        return channel == "brow_inner_raise" || channel == "brow_outer_raise" || channel == "cheek_raise";
    }

    const HeadBuild& m_h;
    std::vector<float> m_speech_mask, m_expression_mask;
    json m_transforms = json::array();
};

// The jaw: JawDrop's jaw rotation, calibrated so 1 opens the incisors 20 mm.
void add_jaw_channel(const HeadBuild& h, const HeadLandmarks& l, RigTransforms& rig) {
    const glm::quat q = glm::quat_cast(h.unit("JawDrop").at("jaw"));
    const glm::vec3 pivot = h.pivot_of("jaw");
    glm::vec3 lower(0.0f);
    for (auto i : l.lower_incisors) lower += h.rest_pos[i];
    lower /= float(l.lower_incisors.size());
    const glm::vec3 moved = pivot + q * (lower - pivot);
    const float gap = lower.y - moved.y;
    if (!(gap > 1.0f)) throw std::runtime_error("head tool: JawDrop does not open the jaw");
    const float jaw_per_unit = 20.0f / gap;
    rig.rotation_and_rest("jaw_rotation", "JawDrop", "jaw", jaw_per_unit,
                          "JawDrop: the jaw about its hinge, 1 = ~20 mm incisor gap");
}

// How a lip or jaw parameter is made from the pose units. Unit weights above
// 1 turn the unit's bones further (a larger natural movement, not a linear
// extrapolation); the lip units leave the jaw bone to jaw_rotation.
struct UnitMapping {
    const char* channel;
    std::vector<std::pair<const char*, float>> positive;
    std::vector<std::pair<const char*, float>> negative;  // empty: the positive shape extends
    const char* note;
    bool with_jaw = false;
    // A translation (mm) of the lower lip's bones (special04's subtree,
    // weighted by their skinning) added to the negative or positive end:
    // where the units cannot press the lips together or tuck the lower
    // lip under the upper teeth on their own.
    glm::vec3 lower_lip_lift_positive{0.0f}, lower_lip_lift_negative{0.0f};
    // Bones of the units left out: the corner pulls keep to the corners
    // (their midline lip bones would move the whole lips back and forth).
    std::set<std::string> without{};
};

std::vector<UnitMapping> unit_mappings() {
    const std::set<std::string> midline_lip_bones = {"special04", "oris01", "oris02", "oris05", "oris06"};
    return {
        {"lip_rounding", {{"LipsKiss", 1.0f}}, {{"MouthLeftPullSide", 0.6f}, {"MouthRightPullSide", 0.6f}},
         "LipsKiss; negative: both corners pulled half way to the side (the corner stretches add the rest)"},
        {"upper_lip_retraction", {{"UpperLipBackward", 1.0f}}, {{"UpperLipForward", 1.0f}},
         "UpperLipBackward; negative: UpperLipForward"},
        {"upper_lip_raise", {{"UpperLipUp", 1.6f}}, {}, "UpperLipUp; negative: pressed down (the shape reversed)"},
        {"lower_lip_retraction", {{"lowerLipBackward", 0.3f}}, {{"lowerLipForward", 0.5f}},
         "lowerLipBackward and the lower lip lifted under the upper teeth; negative: lowerLipForward", false,
         glm::vec3(0.0f, 6.0f, -3.0f), glm::vec3(0.0f)},
        {"lower_lip_depression", {{"lowerLipDown", 1.0f}}, {{"lowerLipUp", 1.0f}},
         "lowerLipDown; negative: lowerLipUp and the lower lip lifted against the upper", false, glm::vec3(0.0f),
         glm::vec3(0.0f, 12.0f, 0.0f)},
        {"mouth_corner_stretch_left", {{"MouthLeftPullSide", 1.0f}}, {}, "MouthLeftPullSide (corner bones); negative: inward",
         false, glm::vec3(0.0f), glm::vec3(0.0f), midline_lip_bones},
        {"mouth_corner_stretch_right", {{"MouthRightPullSide", 1.0f}}, {}, "MouthRightPullSide (corner bones); negative: inward",
         false, glm::vec3(0.0f), glm::vec3(0.0f), midline_lip_bones},
        {"jaw_thrust", {{"ChinForward", 1.0f}}, {}, "ChinForward; negative: back", true},
        {"jaw_shift", {{"ChinLeft", 1.0f}}, {{"ChinRight", 1.0f}}, "ChinLeft; negative: ChinRight", true},
    };
}

// The lip and jaw parameters (every articulatory parameter but the jaw
// rotation) as blendshapes of their units, scaled to the parameter's range.
void add_lip_and_jaw_channels(const HeadBuild& h, RigTransforms& rig) {
    const auto lower_lip_share = subtree_weight(h, "special04");
    for (const auto& m : unit_mappings()) {
        const auto param = synth::param_from_name(m.channel);
        AVSI_ASSERT(param.has_value());
        const auto& info = synth::param_info(*param);
        auto combine = [&](const std::vector<std::pair<const char*, float>>& parts) {
            MhPose pose;
            for (const auto& [name, w] : parts)
                for (const auto& [bone, r] : h.unit(name))
                    if ((m.with_jaw || bone != "jaw") && !m.without.count(bone))
                        pose[bone] = scaled_rotation(r, w) * (pose.count(bone) ? pose[bone] : glm::mat3(1.0f));
            return pose;
        };
        auto with_lift = [&](std::vector<glm::vec3> d, glm::vec3 lift) {
            if (lift != glm::vec3(0.0f))
                for (std::size_t i = 0; i < h.n; ++i) d[i] += lift * lower_lip_share[i];
            return d;
        };
        const auto d = with_lift(pose_displacement(h, combine(m.positive)), m.lower_lip_lift_positive);
        if (m.negative.empty()) {
            rig.blendshape(m.channel, d, float(1.0 / info.max), nullptr, m.note);
        } else {
            rig.blendshape(m.channel, d, float(1.0 / info.max), "positive", m.note);
            // The range's negative end is the opposite unit at its weight.
            rig.blendshape(m.channel, with_lift(pose_displacement(h, combine(m.negative)), m.lower_lip_lift_negative),
                           float(1.0 / info.min), "negative", m.note);
        }
    }
}

// The eyelids, the gaze (each eyeball turns about its centre on its bone)
// and the tongue tip.
void add_eye_and_tongue_channels(const HeadBuild& h, RigTransforms& rig) {
    rig.rotation_and_rest("blink", "LeftUpperLidClosed", "orbicularis03.L", 1.0f, "LeftUpperLidClosed: the upper lid closes");
    rig.rotation_and_rest("blink", "RightUpperLidClosed", "orbicularis03.R", 1.0f, "RightUpperLidClosed: the upper lid closes");
    rig.rotation_and_rest("gaze_left", "LeftEyeturnLeft", "eye.L", 1.0f, "LeftEyeturnLeft: the eyes turn to the speaker's left");
    rig.rotation_and_rest("gaze_left", "RightEyeturnLeft", "eye.R", 1.0f, "RightEyeturnLeft");
    rig.rotation_and_rest("gaze_up", "LeftEyeUp", "eye.L", 1.0f, "LeftEyeUp: the eyes turn up (negative: down)");
    rig.rotation_and_rest("gaze_up", "RightEyeUp", "eye.R", 1.0f, "RightEyeUp");
    rig.blendshape("tongue_tip", pose_displacement(h, pose_of(h, {{"TonguePointUp", 0.6f}, {"TongueOut", 0.6f}})), 1.0f, nullptr,
                   "TonguePointUp and a little TongueOut: the tip raised and forward to the upper teeth and alveolar ridge");
}

// The expressions (animation layers): brows and cheeks, both sides together.
void add_expression_channels(const HeadBuild& h, RigTransforms& rig) {
    rig.blendshape("brow_inner_raise", pose_displacement(h, pose_of(h, {{"LeftInnerBrowUp", 1.0f}, {"RightInnerBrowUp", 1.0f}})),
                   1.0f, "positive", "Left/RightInnerBrowUp: the inner brows raised");
    rig.blendshape("brow_inner_raise", pose_displacement(h, pose_of(h, {{"LeftBrowDown", 1.0f}, {"RightBrowDown", 1.0f}})), -1.0f,
                   "negative", "Left/RightBrowDown: the brows lowered and drawn together (a frown)");
    rig.blendshape("brow_outer_raise", pose_displacement(h, pose_of(h, {{"LeftOuterBrowUp", 1.0f}, {"RightOuterBrowUp", 1.0f}})),
                   1.0f, nullptr, "Left/RightOuterBrowUp: the outer brows raised (negative: the shape reversed)");
    rig.blendshape("cheek_raise", pose_displacement(h, pose_of(h, {{"LeftCheekUp", 1.0f}, {"RightCheekUp", 1.0f}})), 1.0f, nullptr,
                   "Left/RightCheekUp: the cheeks raised (negative: the shape reversed); kept off the lips");
}

// Step 7: the rig's transforms, in the rig file's order: the jaw, the lip
// and jaw parameters, the eyes and the tongue, the expressions.
json rig_transforms(const HeadBuild& h, const HeadLandmarks& l) {
    RigTransforms rig(h);
    add_jaw_channel(h, l, rig);
    add_lip_and_jaw_channels(h, rig);
    add_eye_and_tongue_channels(h, rig);
    add_expression_channels(h, rig);
    return rig.transforms();
}

// Step 8: the vertex colours: ambient occlusion of the mouth's interior
// (darker the deeper behind the lips), on the texture; the shirt's colour.
std::vector<glm::vec3> vertex_colours(const HeadBuild& h, const HeadLandmarks& l) {
    std::vector<glm::vec3> colors(h.n, glm::vec3(1.0f));
    std::vector<float> shade(h.n, 1.0f);
    const float front = l.mouth_middle.z;
    for (std::size_t t = 0; t < h.out.triangles.size(); ++t) {
        const auto& g = h.out.triangle_group[t];
        float near = 1.0f, far = 1.0f, reach = 1.0f;
        if (g.find("cavity") != std::string::npos) near = 0.4f, far = 0.08f, reach = 25.0f;
        else if (g.find("inner") != std::string::npos) near = 1.0f, far = 0.55f, reach = 10.0f;
        else if (g.find("teeth") != std::string::npos) near = 1.0f, far = 0.30f, reach = 30.0f;
        else if (g == "tongue") near = 0.6f, far = 0.18f, reach = 30.0f;
        else continue;
        for (auto i : h.out.triangles[t]) {
            const float depth = std::max(0.0f, front - h.rest_pos[i].z);
            shade[i] = std::min(shade[i], near + (far - near) * smoothstep(0.0f, reach, depth));
        }
    }
    for (std::size_t i = 0; i < h.n; ++i) colors[i] = h.out.vertices[i].part == 3 ? shirt_color : glm::vec3(shade[i]);
    return colors;
}

// The OBJ text: vertices with their colours, texture coordinates, and the
// faces by group, groups in a fixed order.
std::string head_obj_text(const HeadBuild& h, const std::vector<glm::vec3>& colors, const std::string& png_name) {
    const std::size_t n = h.n;
    const auto& out = h.out;
    std::string obj = fmt::format(
        "# avsi built-in talking head ({} variant), made by stimuli/tools/make_head.cpp (scripts/make-head)\n"
        "# from the MakeHuman assets (CC0 1.0, makehumancommunity): base mesh, proxies, targets, textures.\n"
        "# Units: mm; x = speaker's left, y = up, z = forward. Vertex colours: linear RGB multipliers of the\n"
        "# texture {} (ambient occlusion of the mouth). {} vertices, {} triangles.\n",
        h.variant.label, png_name, n, out.triangles.size());
    obj.reserve(n * 80 + out.triangles.size() * 40);
    for (std::size_t i = 0; i < n; ++i)
        obj += fmt::format("v {:.3f} {:.3f} {:.3f} {:.3f} {:.3f} {:.3f}\n", h.rest_pos[i].x, h.rest_pos[i].y,
                           h.rest_pos[i].z, colors[i].r, colors[i].g, colors[i].b);
    for (std::size_t i = 0; i < n; ++i)
        obj += fmt::format("vt {:.6f} {:.6f}\n", out.vertices[i].uv.x, out.vertices[i].uv.y);
    const std::vector<std::string> group_order = {"shirt", "skin",        "upper_lip",   "lower_lip",   "upper_inner", "lower_inner",
                                                  "upper_cavity", "lower_cavity", "upper_teeth", "lower_teeth", "tongue",
                                                  "eyes",        "cornea",      "brows",       "lashes",      "hair"};
    for (const auto& g : group_order) {
        bool any = false;
        for (std::size_t t = 0; t < out.triangles.size(); ++t) {
            if (out.triangle_group[t] != g) continue;
            if (!any) obj += "g " + g + "\n", any = true;
            const auto& tri = out.triangles[t];
            obj += fmt::format("f {0}/{0} {1}/{1} {2}/{2}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1);
        }
    }
    return obj;
}

// The rig's fields but the transforms: the files, landmarks, articulation
// vertices, lip contact and materials.
json rig_fields(const HeadBuild& h, const HeadLandmarks& l, const std::string& obj_name, const std::string& png_name) {
    json rig;
    rig["format"] = "avsi-rig";
    rig["version"] = 2;
    rig["units"] = "mm";
    rig["mesh"] = obj_name;
    rig["texture"] = png_name;
    rig["variant"] = h.variant.label;
    rig["generator"] = "avsi::stimuli::build_head (stimuli/src/head_builder.cpp), scripts/make-head";
    rig["source"] = "MakeHuman assets, CC0 1.0 (../shared/assets/makehuman/README.md)";
    const float head_top = l.crown + 20.0f;
    rig["landmarks"] = {
        {"left_eye", vec3_json(h.to_mm(h.eye_left))},
        {"right_eye", vec3_json(h.to_mm(h.eye_right))},
        {"nose_bottom", vec3_json(l.nose_bottom)},
        {"mouth_left", vec3_json(h.P(l.corner_left))},
        {"mouth_right", vec3_json(h.P(l.corner_right))},
        {"mouth_middle", vec3_json(l.mouth_middle)},
        {"iris_diameter", round_to(l.iris, 0.001)},
        // The frame's centre for head-and-shoulders framing (RenderSettings):
        // the crown 20 mm below the top of a 340 mm-high view.
        {"head_center", vec3_json(glm::vec3(0.0f, head_top - 170.0f, 0.0f))},
        {"head_height", round_to(l.crown - l.chin.y, 0.001)},
        // The head's rotation pivot (animation layers): the head bone's joint on the neck.
        {"neck_pivot", vec3_json(h.pivot_of("head"))},
    };
    auto ids = [](const std::vector<std::uint32_t>& v) { return json(v); };
    rig["articulation"] = {
        {"upper_lip_contour", ids(l.upper_contour)},
        {"lower_lip_contour", ids(l.lower_contour)},
        {"mouth_corners", json::array({h.out.of_base(l.corner_left), h.out.of_base(l.corner_right)})},
        {"upper_lip_point", l.upper_point},
        {"lower_lip_point", l.lower_point},
        {"upper_incisor_edge", ids(l.upper_incisors)},
        {"lower_incisor_edge", ids(l.lower_incisors)},
        {"lower_lip_surface", ids(l.lip_surface)},
        {"up", json::array({0, 1, 0})},
        {"forward", json::array({0, 0, 1})},
    };
    rig["lip_contact"] = {{"upper", {{"groups", {"upper_lip", "upper_inner", "upper_cavity"}}}},
                          {"lower", {{"groups", {"lower_lip", "lower_inner", "lower_cavity"}}}},
                          {"reach_mm", 6.0}};
    rig["materials"] = {
        {"skin", {{"specular", 0.10}, {"shininess", 14.0}, {"wrap", 0.35}}},
        {"shirt", {{"specular", 0.03}, {"shininess", 6.0}, {"wrap", 0.5}}},
        {"upper_lip", {{"specular", 0.16}, {"shininess", 22.0}, {"wrap", 0.35}}},
        {"lower_lip", {{"specular", 0.16}, {"shininess", 22.0}, {"wrap", 0.35}}},
        {"upper_inner", {{"specular", 0.14}, {"shininess", 24.0}, {"wrap", 0.5}}},
        {"lower_inner", {{"specular", 0.14}, {"shininess", 24.0}, {"wrap", 0.5}}},
        {"upper_cavity", {{"specular", 0.02}, {"shininess", 8.0}, {"wrap", 0.7}}},
        {"lower_cavity", {{"specular", 0.02}, {"shininess", 8.0}, {"wrap", 0.7}}},
        {"upper_teeth", {{"specular", 0.25}, {"shininess", 40.0}, {"wrap", 0.3}}},
        {"lower_teeth", {{"specular", 0.25}, {"shininess", 40.0}, {"wrap", 0.3}}},
        {"tongue", {{"specular", 0.2}, {"shininess", 26.0}, {"wrap", 0.5}}},
        {"eyes", {{"specular", 0.3}, {"shininess", 60.0}, {"wrap", 0.2}}},
        {"cornea", {{"specular", 1.2}, {"shininess", 300.0}, {"wrap", 0.0}, {"blend", true}}},
        {"brows", {{"specular", 0.0}, {"shininess", 8.0}, {"wrap", 0.4}, {"blend", true}}},
        {"lashes", {{"specular", 0.0}, {"shininess", 8.0}, {"wrap", 0.4}, {"blend", true}}},
        {"hair", {{"specular", 0.12}, {"shininess", 20.0}, {"wrap", 0.4}, {"blend", true}}},
    };
    return rig;
}

// The rig file's text: one line per top-level field and per transform:
// readable, and a change to one transform is a one-line diff.
std::string rig_text(const json& rig, const json& transforms) {
    std::string text = "{\n";
    for (const auto& [key, value] : rig.items()) text += " " + json(key).dump() + ": " + value.dump() + ",\n";
    text += " \"transforms\": [\n";
    for (std::size_t k = 0; k < transforms.size(); ++k)
        text += "  " + transforms[k].dump() + (k + 1 < transforms.size() ? ",\n" : "\n");
    text += " ]\n}\n";
    return text;
}

// Step 9: <stem>.png (the atlas), <stem>.obj and <stem>.rig.json into the output folder.
void write_head_files(const HeadBuild& h, const HeadLandmarks& l, const json& transforms,
                      const std::vector<glm::vec3>& colors) {
    const std::string stem = head_variant_stem(h.settings.variant);
    const std::filesystem::path obj_path = h.settings.out_dir / (stem + ".obj");
    const std::filesystem::path rig_path = h.settings.out_dir / (stem + ".rig.json");
    const std::filesystem::path png_path = h.settings.out_dir / (stem + ".png");
    write_png_rgba(png_path, h.atlas.render());
    write_text_file(obj_path, head_obj_text(h, colors, png_path.filename().string()));
    write_text_file(rig_path, rig_text(rig_fields(h, l, obj_path.filename().string(), png_path.filename().string()),
                                       transforms));
}

}  // namespace

void build_head(const HeadBuildSettings& settings) {
    if (!std::filesystem::is_directory(settings.assets_dir))
        throw InputError(settings.assets_dir,
                         "not a folder: expected the MakeHuman assets (mesh/, rig/, poses/, proxies/, targets/, textures/)");
    HeadBuild h(settings, variant_of(settings.variant));
    shape_base_mesh(h);
    add_proxies(h);
    cut_head_and_mouth(h);
    place_head_frame(h);
    assemble_mesh(h);
    const HeadLandmarks landmarks = pick_landmarks(h);
    const json transforms = rig_transforms(h, landmarks);
    write_head_files(h, landmarks, transforms, vertex_colours(h, landmarks));
}

}  // namespace avsi::stimuli
