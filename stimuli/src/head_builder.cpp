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
#include <set>

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

void build_head(const HeadBuildSettings& settings) {
    const auto& dir = settings.assets_dir;
    if (!std::filesystem::is_directory(dir))
        throw InputError(dir, "not a folder: expected the MakeHuman assets (mesh/, rig/, poses/, proxies/, targets/, textures/)");
    const Variant variant = variant_of(settings.variant);
    const std::string stem = head_variant_stem(settings.variant);

    // 1. The base mesh, shaped by the variant's macro targets.
    const MhMesh base = read_mh_obj(dir / "mesh" / "base.obj");
    std::vector<glm::vec3> shaped = base.positions;
    for (const auto& [file, weight] : variant.targets) apply_target(read_target(dir / "targets" / file), weight, shaped);

    const MhSkeleton skeleton = read_skeleton(dir / "rig" / "default.mhskel", dir / "rig" / "default_weights.mhw");
    // The shape targets part the lips slightly; at rest they just meet: the
    // lower lip's bones' region is raised until the midline gap is 0.02 mm.
    {
        const int lip = skeleton.bone_index("special04");
        if (lip < 0) throw InputError(dir / "rig" / "default.mhskel", "no bone \"special04\" (the lower lip's)");
        std::vector<float> in(shaped.size(), 0.0f), total(shaped.size(), 0.0f);
        for (std::size_t b = 0; b < skeleton.bones.size(); ++b)
            for (const auto& [v, w] : skeleton.weights[b]) {
                if (v >= in.size()) continue;
                total[v] += w;
                if (skeleton.descends_from(int(b), lip)) in[v] += w;
            }
        const float gap = shaped[upper_lip_edge_vertex].y - shaped[lower_lip_inner_vertex].y - 0.02f / mm_per_unit;
        if (gap > 0)
            for (std::size_t v = 0; v < shaped.size(); ++v)
                if (total[v] > 0) shaped[v].y += gap * in[v] / total[v];
    }
    const auto rest = rest_frames(skeleton, shaped);
    const auto units = read_pose_units(dir / "poses" / "face-poseunits.bvh", dir / "poses" / "face-poseunits.json");
    auto unit = [&](const std::string& name) -> const MhPose& {
        const auto it = units.find(name);
        if (it == units.end()) throw InputError(dir / "poses" / "face-poseunits.json", "no pose unit \"" + name + "\"");
        return it->second;
    };

    // 2. Proxies.
    std::vector<Proxy> proxies;
    auto add_proxy = [&](const std::string& name, const std::string& group) {
        proxies.push_back({read_mhclo(dir / "proxies" / (name + ".mhclo")), group, -1});
    };
    add_proxy("high-poly", "eyes");
    add_proxy(variant.brows, "brows");
    add_proxy("eyelashes01", "lashes");
    add_proxy("teeth_base", "");
    add_proxy("tongue01", "tongue");
    add_proxy("short02", "hair");
    const char* proxy_textures[] = {"brown_eye.png", nullptr, "eyelashes01.png", "teeth.png", "tongue01_diffuse.png",
                                    "short02_diffuse.png"};
    const float proxy_scales[] = {0.25f, 0.5f, 0.5f, 0.25f, 0.25f, 0.25f};
    const bool proxy_alpha[] = {true, true, true, false, false, true};

    // 3. Faces of the body: the head cut and the mouth.
    std::vector<char> body_face(base.faces.size(), 0);
    for (std::size_t f = 0; f < base.faces.size(); ++f)
        body_face[f] = base.group_names[static_cast<std::size_t>(base.faces[f].group)] == "body";
    const Topology topo(base, body_face);
    std::vector<char> keep(base.faces.size(), 0);
    for (std::size_t f = 0; f < base.faces.size(); ++f) {
        if (!body_face[f]) continue;
        bool inside = true;
        for (auto v : base.faces[f].v)
            inside = inside && shaped[v].y > cut_height && std::abs(shaped[v].x) < cut_half_width;
        keep[f] = inside;
    }
    // The lip line (loop A: the upper lip's lower edge and the lower lip's
    // front edge) and the inner loop (B), walked from the midline vertices.
    auto loop_through = [&](std::uint32_t v) {
        // The neighbour toward the speaker's left most nearly level with v.
        std::uint32_t side = v;
        for (auto n : topo.neighbours[v])
            if (shaped[n].x > shaped[v].x &&
                (side == v || std::abs(shaped[n].y - shaped[v].y) < std::abs(shaped[side].y - shaped[v].y)))
                side = n;
        auto l = topo.loop(v, side);
        if (l.size() < 8)
            throw InputError(dir / "mesh" / "base.obj",
                             "no closed edge loop through vertex " + std::to_string(v) + " (the hm08 base mesh has one there)");
        return l;
    };
    const auto loop_a = loop_through(upper_lip_edge_vertex);
    const auto loop_b = loop_through(lower_lip_inner_vertex);
    std::set<std::pair<std::uint32_t, std::uint32_t>> loop_a_edges;
    for (std::size_t k = 0; k < loop_a.size(); ++k) {
        const auto a = loop_a[k], b = loop_a[(k + 1) % loop_a.size()];
        loop_a_edges.insert({std::min(a, b), std::max(a, b)});
    }
    // The mouth bag: faces reached from the mouth floor without crossing the lip line.
    std::vector<char> cavity(base.faces.size(), 0);
    {
        std::vector<std::uint32_t> stack;
        for (auto f : topo.faces_of[mouth_floor_vertex]) cavity[f] = 1, stack.push_back(f);
        while (!stack.empty()) {
            const auto f = stack.back();
            stack.pop_back();
            const auto& v = base.faces[f].v;
            for (std::size_t k = 0; k < v.size(); ++k) {
                const auto a = v[k], b = v[(k + 1) % v.size()];
                if (loop_a_edges.count({std::min(a, b), std::max(a, b)})) continue;
                for (auto g : topo.faces_of[a]) {
                    if (cavity[g]) continue;
                    const auto& w = base.faces[g].v;
                    if (std::find(w.begin(), w.end(), b) == w.end()) continue;
                    cavity[g] = 1;
                    stack.push_back(g);
                }
            }
        }
    }
    std::set<std::uint32_t> on_loop_a(loop_a.begin(), loop_a.end()), on_loop_b(loop_b.begin(), loop_b.end());
    // Lips: faces within a few rings of the lip line, outside the mouth.
    std::vector<int> ring(base.positions.size(), 1 << 20);
    {
        std::vector<std::uint32_t> frontier(loop_a.begin(), loop_a.end());
        for (auto v : loop_a) ring[v] = 0;
        for (int r = 1; r <= 6; ++r) {
            std::vector<std::uint32_t> next;
            for (auto v : frontier)
                for (auto f : topo.faces_of[v]) {
                    if (cavity[f]) continue;
                    for (auto w : base.faces[f].v)
                        if (ring[w] > r) ring[w] = r, next.push_back(w);
                }
            frontier.swap(next);
        }
    }

    // 4. The rest geometry and the posed geometry of a pose (mm, head frame).
    auto fitted = [&](const std::vector<glm::vec3>& b) {
        std::vector<std::vector<glm::vec3>> out;
        for (const auto& p : proxies) out.push_back(fit_proxy(p.proxy, b));
        return out;
    };
    const auto rest_proxies = fitted(shaped);
    // The origin: between the means of the eye proxy's two halves (the
    // frame of the committed heads). Each eyeball's centre, its pivot: the
    // middle of its bounding box (the vertices crowd at the back, so their
    // mean lies about 5 mm in front of it).
    glm::vec3 eye_sum[2] = {glm::vec3(0.0f), glm::vec3(0.0f)};
    float eye_count[2] = {0, 0};
    glm::vec3 eye_lo[2] = {glm::vec3(1e9f), glm::vec3(1e9f)}, eye_hi[2] = {glm::vec3(-1e9f), glm::vec3(-1e9f)};
    for (const auto& p : rest_proxies[0]) {
        const int side = p.x > 0 ? 0 : 1;  // 0: the speaker's left (+x)
        eye_sum[side] += p;
        eye_count[side] += 1;
        eye_lo[side] = glm::min(eye_lo[side], p);
        eye_hi[side] = glm::max(eye_hi[side], p);
    }
    if (eye_count[0] == 0 || eye_count[1] == 0) throw InputError(dir / "proxies" / "high-poly.mhclo", "expected two eyes");
    const glm::vec3 eye_mean_left = eye_sum[0] / eye_count[0], eye_mean_right = eye_sum[1] / eye_count[1];
    const glm::vec3 eye_left = 0.5f * (eye_lo[0] + eye_hi[0]), eye_right = 0.5f * (eye_lo[1] + eye_hi[1]);
    const glm::vec3 origin(0.0f, 0.5f * (eye_mean_left.y + eye_mean_right.y), 0.5f * (eye_mean_left.z + eye_mean_right.z));
    auto to_mm = [&](glm::vec3 p) { return (p - origin) * mm_per_unit; };

    // 5. The output mesh: the kept body faces and the proxies, split at UV seams.
    Atlas atlas;
    const ImageRgba skin_image = read_image_rgba(dir / "textures" / variant.skin);
    const int skin_source = atlas.add_source(skin_image, settings.skin_texture_scale, false);
    // The skin's UV islands among the kept faces: one atlas rectangle each.
    std::vector<int> island_of_vt(base.uvs.size(), -1);
    {
        std::vector<std::uint32_t> parent(base.uvs.size());
        std::iota(parent.begin(), parent.end(), 0u);
        std::function<std::uint32_t(std::uint32_t)> find = [&](std::uint32_t x) {
            while (parent[x] != x) x = parent[x] = parent[parent[x]];
            return x;
        };
        for (std::size_t f = 0; f < base.faces.size(); ++f) {
            if (!keep[f] && !cavity[f]) continue;
            const auto& vt = base.faces[f].vt;
            if (vt.empty()) throw InputError(dir / "mesh" / "base.obj", "a face of the body has no texture coordinates");
            for (std::size_t k = 1; k < vt.size(); ++k) parent[find(vt[k])] = find(vt[0]);
        }
        std::map<std::uint32_t, std::array<float, 4>> box;  // root → u0 v0 u1 v1
        for (std::size_t f = 0; f < base.faces.size(); ++f) {
            if (!keep[f] && !cavity[f]) continue;
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
            const float w = float(skin_image.width), h = float(skin_image.height);
            rect_of_root[root] = atlas.add_rect(skin_source, int(std::floor(b[0] * w)) - pad,
                                                int(std::floor((1.0f - b[3]) * h)) - pad, int(std::ceil(b[2] * w)) + pad,
                                                int(std::ceil((1.0f - b[1]) * h)) + pad);
        }
        for (std::size_t t = 0; t < base.uvs.size(); ++t)
            if (box.count(find(static_cast<std::uint32_t>(t)))) island_of_vt[t] = rect_of_root[find(static_cast<std::uint32_t>(t))];
    }
    for (std::size_t p = 0; p < proxies.size(); ++p) {
        const char* file = proxy_textures[p] ? proxy_textures[p] : nullptr;
        const std::string name = file ? std::string(file) : proxies[p].proxy.name + ".png";
        const ImageRgba img = read_image_rgba(dir / "textures" / name);
        const int s = atlas.add_source(img, proxy_scales[p], proxy_alpha[p]);
        proxies[p].atlas_rect = atlas.add_rect(s, 0, 0, img.width, img.height);
    }
    // A white patch the shirt samples (its colour is the vertex colour).
    int white_rect = -1;
    {
        ImageRgba white;
        white.width = white.height = 8;
        white.rgba.assign(8 * 8 * 4, 255);
        white_rect = atlas.add_rect(atlas.add_source(white, 1.0f, false), 0, 0, 8, 8);
    }
    atlas.pack();
    const glm::vec2 white_uv = atlas.map(white_rect, glm::vec2(0.5f, 0.5f));
    // The shirt: the kept faces reached from the chest without crossing the neckline loop.
    std::vector<char> shirt_face(base.faces.size(), 0);
    {
        const auto neckline = loop_through(neckline_vertex);
        std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
        for (std::size_t k = 0; k < neckline.size(); ++k) {
            const auto a = neckline[k], b = neckline[(k + 1) % neckline.size()];
            edges.insert({std::min(a, b), std::max(a, b)});
        }
        std::vector<std::uint32_t> stack;
        for (auto f : topo.faces_of[chest_vertex])
            if (keep[f]) shirt_face[f] = 1, stack.push_back(f);
        while (!stack.empty()) {
            const auto f = stack.back();
            stack.pop_back();
            const auto& v = base.faces[f].v;
            for (std::size_t k = 0; k < v.size(); ++k) {
                const auto a = v[k], b = v[(k + 1) % v.size()];
                if (edges.count({std::min(a, b), std::max(a, b)})) continue;
                for (auto g : topo.faces_of[a]) {
                    if (shirt_face[g] || !keep[g] || cavity[g]) continue;
                    const auto& w = base.faces[g].v;
                    if (std::find(w.begin(), w.end(), b) == w.end()) continue;
                    shirt_face[g] = 1;
                    stack.push_back(g);
                }
            }
        }
    }

    Assembled out;
    std::vector<std::string> face_group;
    // JawDrop at full weight tells the lower jaw's parts from the upper ones.
    const auto jaw_drop_base = skin(skeleton, skinning_matrices(skeleton, rest, unit("JawDrop")), shaped);
    // Upper or lower: by the hop distance to the lip line's upper and lower
    // arcs (loop A split at its corners), ties by whether JawDrop moves the face.
    std::vector<int> hops_upper(base.positions.size(), 1 << 20), hops_lower(base.positions.size(), 1 << 20);
    {
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
            for (int h = 1; !frontier.empty() && h < 400; ++h) {
                std::vector<std::uint32_t> next;
                for (auto v : frontier)
                    for (auto w : topo.neighbours[v])
                        if (hops[w] > h) hops[w] = h, next.push_back(w);
                frontier.swap(next);
            }
        }
    }
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
        const bool shirt = shirt_face[f] != 0;
        if (shirt) {
            std::vector<std::uint32_t> corners;
            for (std::size_t k = 0; k < face.v.size(); ++k) corners.push_back(out.vertex(-1, face.v[k], 0, white_uv, 3));
            for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
                out.triangles.push_back({corners[0], corners[k], corners[k + 1]});
                out.triangle_group.push_back("shirt");
            }
            continue;
        }
        if (cavity[f]) {
            // The lips' inner surfaces: the faces on either of the two loops.
            bool band = false;
            for (auto v : face.v) band = band || on_loop_a.count(v) || on_loop_b.count(v);
            group = std::string(lower ? "lower" : "upper") + (band ? "_inner" : "_cavity");
        } else {
            int far = 0;
            for (auto v : face.v) far = std::max(far, ring[v]);
            if (far <= 4) group = lower ? "lower_lip" : "upper_lip";
        }
        std::vector<std::uint32_t> corners;
        for (std::size_t k = 0; k < face.v.size(); ++k)
            corners.push_back(out.vertex(-1, face.v[k], face.vt[k],
                                         atlas.map(island_of_vt[face.vt[k]], base.uvs[face.vt[k]])));
        for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
            out.triangles.push_back({corners[0], corners[k], corners[k + 1]});
            out.triangle_group.push_back(group);
        }
    }
    // Teeth: upper or lower by the helper they follow.
    std::set<std::uint32_t> upper_teeth_helper;
    for (const auto& f : base.faces)
        if (base.group_names[static_cast<std::size_t>(f.group)] == "helper-upper-teeth")
            upper_teeth_helper.insert(f.v.begin(), f.v.end());
    for (std::size_t p = 0; p < proxies.size(); ++p) {
        const auto& m = proxies[p].proxy.mesh;
        for (const auto& face : m.faces) {
            if (face.vt.size() != face.v.size())
                throw InputError(dir / "proxies" / (proxies[p].proxy.name + ".obj"), "a face has no texture coordinates");
            std::string group = proxies[p].group;
            if (group == "eyes") {
                // The eye's transparent shell (its texels have no alpha) is the cornea.
                const auto& img = atlas.sources[static_cast<std::size_t>(atlas.rects[static_cast<std::size_t>(proxies[p].atlas_rect)].source)].image;
                glm::vec2 c(0.0f);
                for (auto t : face.vt) c += m.uvs[t];
                c /= float(face.vt.size());
                const int x = std::clamp(int(c.x * float(img.width)), 0, img.width - 1);
                const int y = std::clamp(int((1.0f - c.y) * float(img.height)), 0, img.height - 1);
                if (img.rgba[(std::size_t(y) * std::size_t(img.width) + std::size_t(x)) * 4 + 3] < 128) group = "cornea";
            }
            if (group.empty())
                group = upper_teeth_helper.count(proxies[p].proxy.refs[face.v[0]][0]) ? "upper_teeth" : "lower_teeth";
            std::vector<std::uint32_t> corners;
            for (std::size_t k = 0; k < face.v.size(); ++k)
                corners.push_back(out.vertex(int(p), face.v[k], face.vt[k], atlas.map(proxies[p].atlas_rect, m.uvs[face.vt[k]]),
                                             group == "upper_teeth" ? 1 : group == "lower_teeth" ? 2 : 0));
            for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
                out.triangles.push_back({corners[0], corners[k], corners[k + 1]});
                out.triangle_group.push_back(group);
            }
        }
    }
    const std::size_t n = out.vertices.size();
    // The teeth are rigid: the upper row stays with the skull, the lower
    // row follows the jaw bone only (the skinning spreads lip bones' weights
    // onto the teeth helpers).
    std::vector<int> teeth_row(n, 0);  // 1 upper, 2 lower
    for (std::size_t i = 0; i < n; ++i) teeth_row[i] = out.vertices[i].part;
    // The teeth proxy sits high and deep behind the lips of these shapes:
    // the upper incisal edge 5 mm above the lip line and 10 mm behind it.
    // Both rows move forward and the upper one down, so the upper incisors'
    // edge sits about 2 mm above the lip line as in a young adult at rest.
    const glm::vec3 upper_teeth_shift(0.0f, -3.0f, 3.5f), lower_teeth_shift(0.0f, -1.5f, 2.5f);
    constexpr int teeth_proxy = 3;
    auto positions_of = [&](const std::vector<glm::vec3>& b) {
        const auto px = fitted(b);
        std::vector<glm::vec3> pos(n);
        for (std::size_t i = 0; i < n; ++i) {
            const auto& o = out.vertices[i];
            pos[i] = to_mm(o.proxy < 0 ? b[o.v] : px[static_cast<std::size_t>(o.proxy)][o.v]);
            if (o.proxy == teeth_proxy) pos[i] += teeth_row[i] == 1 ? upper_teeth_shift : lower_teeth_shift;
        }
        return pos;
    };
    const std::vector<glm::vec3> rest_pos = positions_of(shaped);
    auto pose_of = [&](std::initializer_list<std::pair<const char*, float>> parts) {
        MhPose pose;
        for (const auto& [name, weight] : parts)
            for (const auto& [bone, r] : unit(name)) {
                const glm::mat3 s = scaled_rotation(r, weight);
                const auto it = pose.find(bone);
                pose[bone] = it == pose.end() ? s : s * it->second;
            }
        return pose;
    };
    auto displacement = [&](const MhPose& pose) {
        auto pos = positions_of(skin(skeleton, skinning_matrices(skeleton, rest, pose), shaped));
        for (std::size_t i = 0; i < n; ++i) pos[i] -= rest_pos[i];
        const bool jaw_moves = pose.count("jaw") > 0;
        for (std::size_t i = 0; i < n; ++i)
            if (teeth_row[i] == 1 || (teeth_row[i] == 2 && !jaw_moves)) pos[i] = glm::vec3(0.0f);
        return pos;
    };
    // A bone subtree's share of each output vertex's skinning weights.
    auto subtree_weight = [&](const std::string& bone) {
        const int root = skeleton.bone_index(bone);
        if (root < 0) throw InputError(dir / "rig" / "default.mhskel", "no bone \"" + bone + "\"");
        std::vector<float> in(base.positions.size(), 0.0f), total(base.positions.size(), 0.0f);
        for (std::size_t b = 0; b < skeleton.bones.size(); ++b)
            for (const auto& [v, w] : skeleton.weights[b]) {
                if (v >= in.size()) continue;
                total[v] += w;
                if (skeleton.descends_from(int(b), root)) in[v] += w;
            }
        std::vector<float> share(base.positions.size());
        for (std::size_t v = 0; v < share.size(); ++v) share[v] = total[v] > 0 ? in[v] / total[v] : 0.0f;
        std::vector<float> w(n);
        for (std::size_t i = 0; i < n; ++i) {
            const auto& o = out.vertices[i];
            if (o.proxy < 0) {
                w[i] = share[o.v];
            } else {
                const auto& pr = proxies[static_cast<std::size_t>(o.proxy)].proxy;
                const auto& r = pr.refs[o.v];
                const auto& rw = pr.ref_weights[o.v];
                w[i] = std::clamp(rw.x * share[r[0]] + rw.y * share[r[1]] + rw.z * share[r[2]], 0.0f, 1.0f);
            }
        }
        return w;
    };

    // 6. Landmarks (mm).
    auto P = [&](std::uint32_t base_vertex) { return rest_pos[out.of_base(base_vertex)]; };
    // Loop A's upper half (corner to corner through the upper lip's edge) and
    // loop B's lower half; the corners are loop A's outermost points.
    auto halves = [&](const std::vector<std::uint32_t>& loop, std::uint32_t through) {
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
    };
    const auto [upper_arc, corner_left, corner_right] = halves(loop_a, upper_lip_edge_vertex);
    const auto [lower_arc, corner_left_b, corner_right_b] = halves(loop_b, lower_lip_inner_vertex);
    std::vector<std::uint32_t> upper_contour, lower_contour;
    std::set<std::uint32_t> used;
    for (auto v : lower_arc) {
        std::uint32_t best = upper_arc[0];
        for (auto u : upper_arc)
            if (std::abs(shaped[u].x - shaped[v].x) < std::abs(shaped[best].x - shaped[v].x)) best = u;
        // Distinct points; pairs near the corners whose edges already meet at rest measure nothing.
        if (!used.insert(best).second || (shaped[best].y - shaped[v].y) * mm_per_unit < 0.05f) continue;
        upper_contour.push_back(out.of_base(best));
        lower_contour.push_back(out.of_base(v));
    }
    // Most forward midline points of the lips.
    auto front_midline = [&](const char* group) {
        std::uint32_t best = 0;
        float z = -1e9f;
        for (std::size_t t = 0; t < out.triangles.size(); ++t) {
            if (out.triangle_group[t] != group) continue;
            for (auto i : out.triangles[t])
                if (std::abs(rest_pos[i].x) < 0.05f && rest_pos[i].z > z) z = rest_pos[i].z, best = i;
        }
        return best;
    };
    const std::uint32_t upper_point = front_midline("upper_lip"), lower_point = front_midline("lower_lip");
    // Incisal edges: the front teeth's lowest (upper) or highest (lower)
    // front points across the central 16 mm, in 2 mm steps.
    auto incisal_edge = [&](const char* group, bool lowest) {
        float z_front = -1e9f;
        std::set<std::uint32_t> verts;
        for (std::size_t t = 0; t < out.triangles.size(); ++t)
            if (out.triangle_group[t] == group) verts.insert(out.triangles[t].begin(), out.triangles[t].end());
        for (auto i : verts) z_front = std::max(z_front, rest_pos[i].z);
        std::vector<std::uint32_t> edge;
        for (float x = -8.0f; x <= 8.01f; x += 2.0f) {
            std::uint32_t best = 0;
            float y = lowest ? 1e9f : -1e9f;
            bool found = false;
            for (auto i : verts) {
                const auto& p = rest_pos[i];
                if (std::abs(p.x - x) > 1.0f || p.z < z_front - 4.0f) continue;
                if (lowest ? p.y < y : p.y > y) y = p.y, best = i, found = true;
            }
            if (found && (edge.empty() || edge.back() != best)) edge.push_back(best);
        }
        if (edge.size() < 2) throw std::runtime_error(std::string("head tool: no incisal edge found on the ") + group);
        return edge;
    };
    const auto upper_incisors = incisal_edge("upper_teeth", true);
    const auto lower_incisors = incisal_edge("lower_teeth", false);
    // The lower lip's upper surface: its inner band and the outer rows next
    // to the lip line, across the central 24 mm.
    std::vector<std::uint32_t> lip_surface;
    {
        std::set<std::uint32_t> s;
        for (std::size_t t = 0; t < out.triangles.size(); ++t) {
            const auto& g = out.triangle_group[t];
            if (g != "lower_inner" && g != "lower_lip") continue;
            for (auto i : out.triangles[t]) {
                const auto& o = out.vertices[i];
                if (o.proxy >= 0 || std::abs(rest_pos[i].x) > 12.0f) continue;
                if (g == "lower_lip" && ring[o.v] > 4) continue;
                if (out.first.at({-1, o.v}) == i) s.insert(i);
            }
        }
        lip_surface.assign(s.begin(), s.end());
    }
    const glm::vec3 mouth_middle = 0.5f * (P(upper_lip_edge_vertex) + P(lower_lip_inner_vertex));
    // Subnasale: the deepest midline skin point between the lip and the nose tip.
    glm::vec3 nose_bottom(0.0f, 0.0f, -1e9f), chin(0.0f, 1e9f, 0.0f);
    float crown = -1e9f, bottom = 1e9f;
    for (std::size_t i = 0; i < n; ++i) {
        const auto& o = out.vertices[i];
        const auto& p = rest_pos[i];
        crown = std::max(crown, p.y);
        bottom = std::min(bottom, p.y);
        if (o.proxy >= 0 || std::abs(p.x) > 0.05f) continue;
        if (p.y > mouth_middle.y + 8.0f && p.y < mouth_middle.y + 30.0f && p.z > mouth_middle.z - 12.0f &&
            (nose_bottom.z < -1e8f || p.z < nose_bottom.z))
            nose_bottom = p;
        if (p.z > mouth_middle.z - 25.0f && p.y < chin.y && p.y > mouth_middle.y - 70.0f) chin = p;
    }
    // The iris: the width of the left eye's dark (iris-textured) front.
    float iris = 0;
    {
        const auto& img = atlas.sources[static_cast<std::size_t>(atlas.rects[static_cast<std::size_t>(proxies[0].atlas_rect)].source)].image;
        float lo = 1e9f, hi = -1e9f;
        for (const auto& face : proxies[0].proxy.mesh.faces)
            for (std::size_t k = 0; k < face.v.size(); ++k) {
                const glm::vec3 p = to_mm(rest_proxies[0][face.v[k]]);
                if (p.x <= 0) continue;
                const glm::vec2 uv = proxies[0].proxy.mesh.uvs[face.vt[k]];
                const int x = std::clamp(int(uv.x * float(img.width)), 0, img.width - 1);
                const int y = std::clamp(int((1.0f - uv.y) * float(img.height)), 0, img.height - 1);
                const std::uint8_t* c = &img.rgba[(std::size_t(y) * std::size_t(img.width) + std::size_t(x)) * 4];
                if (c[3] < 128 || 0.3f * c[0] + 0.59f * c[1] + 0.11f * c[2] > 110.0f) continue;  // sclera or shell
                lo = std::min(lo, p.x), hi = std::max(hi, p.x);
            }
        if (hi > lo) iris = hi - lo;
    }

    // 7. The rig's transforms.
    json transforms = json::array();
    const double offset_step = 0.001;  // mm
    const float keep_offset_mm = 0.05f;
    // The speech channels move the lower face only: the units' small
    // motions above the cheekbones (temples, under the hair and brows) fade
    // out between 40 and 25 mm below the eyes; eyes, brows, lashes and hair
    // keep still. Static hair and brows then stay static for the renderer.
    // They also fade out beyond the jaw (an ellipsoid round the mouth and
    // chin): the neck and shoulders keep still, so the renderer redraws only
    // the lower face each frame.
    const glm::vec3 mouth_rest = 0.5f * (P(upper_lip_edge_vertex) + P(lower_lip_inner_vertex));
    const glm::vec3 jaw_centre = mouth_rest - glm::vec3(0.0f, 20.0f, 25.0f), jaw_radii(72.0f, 62.0f, 85.0f);
    std::vector<float> speech_mask(n, 1.0f);
    for (std::size_t i = 0; i < n; ++i) {
        const int proxy = out.vertices[i].proxy;
        const float reach = glm::length((rest_pos[i] - jaw_centre) / jaw_radii);
        speech_mask[i] = proxy >= 0 && proxy != teeth_proxy && proxies[static_cast<std::size_t>(proxy)].group != "tongue"
                             ? 0.0f
                             : (1.0f - smoothstep(-40.0f, -25.0f, rest_pos[i].y)) * (1.0f - smoothstep(0.75f, 1.0f, reach));
    }
    // The expression channels (brows, cheeks) move the upper face only:
    // they fade out round the lips (an ellipsoid about the mouth), so no
    // expression can open a lip closure; the eyeballs, teeth and tongue
    // keep still.
    std::vector<float> expression_mask(n, 1.0f);
    const glm::vec3 lips_radii(34.0f, 16.0f, 30.0f);
    for (std::size_t i = 0; i < n; ++i) {
        const int proxy = out.vertices[i].proxy;
        const float reach = glm::length((rest_pos[i] - mouth_rest) / lips_radii);
        const bool still = proxy == 0 || proxy == teeth_proxy ||
                           (proxy > 0 && proxies[static_cast<std::size_t>(proxy)].group == "tongue");
        expression_mask[i] = still ? 0.0f : smoothstep(1.0f, 1.5f, reach);
    }
    auto is_expression = [](const std::string& channel) {
        return channel == "brow_inner_raise" || channel == "brow_outer_raise" || channel == "cheek_raise";
    };
    auto blendshape = [&](const std::string& channel, const std::vector<glm::vec3>& d, float per_unit,
                          const char* side, const std::string& note) {
        json vertices = json::array(), offsets = json::array();
        const bool expression = is_expression(channel);
        const bool speech = channel != "blink" && channel.rfind("gaze", 0) != 0 && !expression;
        for (std::size_t i = 0; i < n; ++i) {
            const glm::vec3 o =
                d[i] * per_unit * (speech ? speech_mask[i] : expression ? expression_mask[i] : 1.0f);
            if (glm::length(o) < keep_offset_mm) continue;
            vertices.push_back(i);
            for (int c = 0; c < 3; ++c) offsets.push_back(round_to(o[c], offset_step));
        }
        json t = {{"channel", channel}, {"note", note}, {"blendshape", {{"vertices", vertices}, {"offsets", offsets}}}};
        if (side) t["side"] = side;
        transforms.push_back(t);
    };
    // A bone's rotation in a unit as a weighted rotation transform, and the
    // rest of the unit's motion as a blendshape on the same channel.
    auto pivot_of = [&](const std::string& bone) {
        return to_mm(glm::vec3(rest[static_cast<std::size_t>(skeleton.bone_index(bone))][3]));
    };
    auto rotation_and_rest = [&](const std::string& channel, const std::string& unit_name, const std::string& bone,
                                 float per_unit, const std::string& note) {
        const MhPose& pose = unit(unit_name);
        const glm::quat q = glm::quat_cast(pose.at(bone));
        const float angle = glm::degrees(glm::angle(q));
        const glm::vec3 axis = glm::axis(q);
        const int b = skeleton.bone_index(bone);
        glm::vec3 pivot = to_mm(glm::vec3(rest[static_cast<std::size_t>(b)][3]));
        auto weights = subtree_weight(bone);
        auto d = displacement(pose);
        if (bone == "eye.L" || bone == "eye.R") {
            // An eyeball turns about its own centre (the bone's head lies
            // 8 mm behind the proxy's), rigidly: no rest for its vertices.
            pivot = to_mm(bone == "eye.L" ? eye_left : eye_right);
            for (std::size_t i = 0; i < n; ++i)
                if (out.vertices[i].proxy == 0) {
                    const bool same_side = (rest_pos[i].x > 0) == (bone == "eye.L");
                    weights[i] = same_side ? 1.0f : 0.0f;
                    const glm::quat r = glm::angleAxis(glm::radians(angle) * weights[i], axis);
                    d[i] = (pivot + r * (rest_pos[i] - pivot)) - rest_pos[i];
                }
        }
        if (bone == "jaw")
            for (std::size_t i = 0; i < n; ++i)
                if (teeth_row[i] != 0) {
                    weights[i] = teeth_row[i] == 2 ? 1.0f : 0.0f;
                    // The lower row turns with the jaw and nothing else.
                    const glm::quat r = glm::angleAxis(glm::angle(glm::quat_cast(pose.at(bone))) * weights[i],
                                                       glm::axis(glm::quat_cast(pose.at(bone))));
                    d[i] = teeth_row[i] == 2 ? (pivot_of(bone) + r * (rest_pos[i] - pivot_of(bone))) - rest_pos[i]
                                             : glm::vec3(0.0f);
                }
        json vertices = json::array(), w = json::array();
        for (std::size_t i = 0; i < n; ++i) {
            const bool speech = channel != "blink" && channel.rfind("gaze", 0) != 0;
            const float wi = float(round_to(weights[i] * (speech ? speech_mask[i] : 1.0f), 0.0001));
            if (wi <= 0.0f) continue;
            vertices.push_back(i);
            w.push_back(wi);
            const glm::quat r = glm::angleAxis(glm::radians(angle) * wi, axis);
            d[i] -= (pivot + r * (rest_pos[i] - pivot)) - rest_pos[i];
        }
        transforms.push_back({{"channel", channel},
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
        return std::make_pair(angle, pivot);
    };

    // The jaw: JawDrop's jaw rotation, calibrated so 1 opens the incisors 20 mm.
    float jaw_per_unit = 1.0f;
    {
        const glm::quat q = glm::quat_cast(unit("JawDrop").at("jaw"));
        const glm::vec3 pivot = to_mm(glm::vec3(rest[static_cast<std::size_t>(skeleton.bone_index("jaw"))][3]));
        glm::vec3 lower(0.0f);
        for (auto i : lower_incisors) lower += rest_pos[i];
        lower /= float(lower_incisors.size());
        const glm::vec3 moved = pivot + q * (lower - pivot);
        const float gap = lower.y - moved.y;
        if (!(gap > 1.0f)) throw std::runtime_error("head tool: JawDrop does not open the jaw");
        jaw_per_unit = 20.0f / gap;
    }
    rotation_and_rest("jaw_rotation", "JawDrop", "jaw", jaw_per_unit,
                      "JawDrop: the jaw about its hinge, 1 = ~20 mm incisor gap");
    // Unit weights above 1 turn the unit's bones further (a larger natural
    // movement, not a linear extrapolation); the lip units leave the jaw bone
    // to jaw_rotation.
    struct Mapping {
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
    const std::set<std::string> midline_lip_bones = {"special04", "oris01", "oris02", "oris05", "oris06"};
    const std::vector<Mapping> mappings = {
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
    const auto lower_lip_share = subtree_weight("special04");
    for (const auto& m : mappings) {
        const auto param = synth::param_from_name(m.channel);
        AVSI_ASSERT(param.has_value());
        const auto& info = synth::param_info(*param);
        auto combine = [&](const std::vector<std::pair<const char*, float>>& parts) {
            MhPose pose;
            for (const auto& [name, w] : parts)
                for (const auto& [bone, r] : unit(name))
                    if ((m.with_jaw || bone != "jaw") && !m.without.count(bone))
                        pose[bone] = scaled_rotation(r, w) * (pose.count(bone) ? pose[bone] : glm::mat3(1.0f));
            return pose;
        };
        const MhPose pos = combine(m.positive);
        auto with_lift = [&](std::vector<glm::vec3> d, glm::vec3 lift) {
            if (lift != glm::vec3(0.0f))
                for (std::size_t i = 0; i < n; ++i) d[i] += lift * lower_lip_share[i];
            return d;
        };
        const auto d = with_lift(displacement(pos), m.lower_lip_lift_positive);
        if (m.negative.empty()) {
            blendshape(m.channel, d, float(1.0 / info.max), nullptr, m.note);
        } else {
            blendshape(m.channel, d, float(1.0 / info.max), "positive", m.note);
            // The range's negative end is the opposite unit at its weight.
            blendshape(m.channel, with_lift(displacement(combine(m.negative)), m.lower_lip_lift_negative),
                       float(1.0 / info.min), "negative", m.note);
        }
    }
    // Eyelids and the tongue tip.
    rotation_and_rest("blink", "LeftUpperLidClosed", "orbicularis03.L", 1.0f, "LeftUpperLidClosed: the upper lid closes");
    rotation_and_rest("blink", "RightUpperLidClosed", "orbicularis03.R", 1.0f, "RightUpperLidClosed: the upper lid closes");
    // Gaze: each eyeball turns about its centre on its bone.
    rotation_and_rest("gaze_left", "LeftEyeturnLeft", "eye.L", 1.0f, "LeftEyeturnLeft: the eyes turn to the speaker's left");
    rotation_and_rest("gaze_left", "RightEyeturnLeft", "eye.R", 1.0f, "RightEyeturnLeft");
    rotation_and_rest("gaze_up", "LeftEyeUp", "eye.L", 1.0f, "LeftEyeUp: the eyes turn up (negative: down)");
    rotation_and_rest("gaze_up", "RightEyeUp", "eye.R", 1.0f, "RightEyeUp");
    blendshape("tongue_tip", displacement(pose_of({{"TonguePointUp", 0.6f}, {"TongueOut", 0.6f}})), 1.0f, nullptr,
               "TonguePointUp and a little TongueOut: the tip raised and forward to the upper teeth and alveolar ridge");
    // Expressions (animation layers): brows and cheeks, both sides together.
    blendshape("brow_inner_raise", displacement(pose_of({{"LeftInnerBrowUp", 1.0f}, {"RightInnerBrowUp", 1.0f}})), 1.0f,
               "positive", "Left/RightInnerBrowUp: the inner brows raised");
    blendshape("brow_inner_raise", displacement(pose_of({{"LeftBrowDown", 1.0f}, {"RightBrowDown", 1.0f}})), -1.0f,
               "negative", "Left/RightBrowDown: the brows lowered and drawn together (a frown)");
    blendshape("brow_outer_raise", displacement(pose_of({{"LeftOuterBrowUp", 1.0f}, {"RightOuterBrowUp", 1.0f}})), 1.0f,
               nullptr, "Left/RightOuterBrowUp: the outer brows raised (negative: the shape reversed)");
    blendshape("cheek_raise", displacement(pose_of({{"LeftCheekUp", 1.0f}, {"RightCheekUp", 1.0f}})), 1.0f, nullptr,
               "Left/RightCheekUp: the cheeks raised (negative: the shape reversed); kept off the lips");

    // 8. Vertex colours: ambient occlusion of the mouth's interior (darker
    // the deeper behind the lips), on the texture.
    std::vector<glm::vec3> colors(n, glm::vec3(1.0f));
    {
        std::vector<float> shade(n, 1.0f);
        const float front = mouth_middle.z;
        for (std::size_t t = 0; t < out.triangles.size(); ++t) {
            const auto& g = out.triangle_group[t];
            float near = 1.0f, far = 1.0f, reach = 1.0f;
            if (g.find("cavity") != std::string::npos) near = 0.4f, far = 0.08f, reach = 25.0f;
            else if (g.find("inner") != std::string::npos) near = 1.0f, far = 0.55f, reach = 10.0f;
            else if (g.find("teeth") != std::string::npos) near = 1.0f, far = 0.30f, reach = 30.0f;
            else if (g == "tongue") near = 0.6f, far = 0.18f, reach = 30.0f;
            else continue;
            for (auto i : out.triangles[t]) {
                const float depth = std::max(0.0f, front - rest_pos[i].z);
                shade[i] = std::min(shade[i], near + (far - near) * smoothstep(0.0f, reach, depth));
            }
        }
        for (std::size_t i = 0; i < n; ++i) colors[i] = out.vertices[i].part == 3 ? shirt_color : glm::vec3(shade[i]);
    }

    // 9. Write.
    const std::filesystem::path obj_path = settings.out_dir / (stem + ".obj");
    const std::filesystem::path rig_path = settings.out_dir / (stem + ".rig.json");
    const std::filesystem::path png_path = settings.out_dir / (stem + ".png");
    write_png_rgba(png_path, atlas.render());

    std::string obj = fmt::format(
        "# avsi built-in talking head ({} variant), made by stimuli/tools/make_head.cpp (scripts/make-head)\n"
        "# from the MakeHuman assets (CC0 1.0, makehumancommunity): base mesh, proxies, targets, textures.\n"
        "# Units: mm; x = speaker's left, y = up, z = forward. Vertex colours: linear RGB multipliers of the\n"
        "# texture {} (ambient occlusion of the mouth). {} vertices, {} triangles.\n",
        variant.label, png_path.filename().string(), n, out.triangles.size());
    obj.reserve(n * 80 + out.triangles.size() * 40);
    for (std::size_t i = 0; i < n; ++i)
        obj += fmt::format("v {:.3f} {:.3f} {:.3f} {:.3f} {:.3f} {:.3f}\n", rest_pos[i].x, rest_pos[i].y, rest_pos[i].z,
                           colors[i].r, colors[i].g, colors[i].b);
    for (std::size_t i = 0; i < n; ++i)
        obj += fmt::format("vt {:.6f} {:.6f}\n", out.vertices[i].uv.x, out.vertices[i].uv.y);
    // Faces by group, groups in a fixed order.
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
    write_text_file(obj_path, obj);

    json rig;
    rig["format"] = "avsi-rig";
    rig["version"] = 2;
    rig["units"] = "mm";
    rig["mesh"] = obj_path.filename().string();
    rig["texture"] = png_path.filename().string();
    rig["variant"] = variant.label;
    rig["generator"] = "avsi::stimuli::build_head (stimuli/src/head_builder.cpp), scripts/make-head";
    rig["source"] = "MakeHuman assets, CC0 1.0 (../shared/assets/makehuman/README.md)";
    const float head_top = crown + 20.0f;
    rig["landmarks"] = {
        {"left_eye", vec3_json(to_mm(eye_left))},
        {"right_eye", vec3_json(to_mm(eye_right))},
        {"nose_bottom", vec3_json(nose_bottom)},
        {"mouth_left", vec3_json(P(corner_left))},
        {"mouth_right", vec3_json(P(corner_right))},
        {"mouth_middle", vec3_json(mouth_middle)},
        {"iris_diameter", round_to(iris, 0.001)},
        // The frame's centre for head-and-shoulders framing (RenderSettings):
        // the crown 20 mm below the top of a 340 mm-high view.
        {"head_center", vec3_json(glm::vec3(0.0f, head_top - 170.0f, 0.0f))},
        {"head_height", round_to(crown - chin.y, 0.001)},
        // The head's rotation pivot (animation layers): the head bone's joint on the neck.
        {"neck_pivot", vec3_json(pivot_of("head"))},
    };
    auto ids = [](const std::vector<std::uint32_t>& v) { return json(v); };
    rig["articulation"] = {
        {"upper_lip_contour", ids(upper_contour)},
        {"lower_lip_contour", ids(lower_contour)},
        {"mouth_corners", json::array({out.of_base(corner_left), out.of_base(corner_right)})},
        {"upper_lip_point", upper_point},
        {"lower_lip_point", lower_point},
        {"upper_incisor_edge", ids(upper_incisors)},
        {"lower_incisor_edge", ids(lower_incisors)},
        {"lower_lip_surface", ids(lip_surface)},
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
    // One line per top-level field and per transform: readable, and a change
    // to one transform is a one-line diff.
    std::string text = "{\n";
    for (const auto& [key, value] : rig.items()) text += " " + json(key).dump() + ": " + value.dump() + ",\n";
    text += " \"transforms\": [\n";
    for (std::size_t k = 0; k < transforms.size(); ++k)
        text += "  " + transforms[k].dump() + (k + 1 < transforms.size() ? ",\n" : "\n");
    text += " ]\n}\n";
    write_text_file(rig_path, text);
}

}  // namespace avsi::stimuli
