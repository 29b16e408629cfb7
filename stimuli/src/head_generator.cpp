// Procedural generator of the built-in talking head (see head_generator.h).
// Units are millimetres; x to the speaker's left (viewer's right), y up, z
// forward out of the face. All shapes are analytic so the file is
// reproducible byte for byte.
#include "avsi/stimuli/head_generator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include "avsi/core/files.h"
#include "smoothstep.h"

namespace avsi::stimuli {

namespace {

constexpr float pi = 3.14159265358979f;

float gauss2(float dx, float sx, float dy, float sy) {
    return std::exp(-(dx / sx) * (dx / sx) - (dy / sy) * (dy / sy));
}
glm::vec3 mix3(glm::vec3 a, glm::vec3 b, float t) { return a + (b - a) * t; }

// Colours (linear RGB).
const glm::vec3 skin_color{0.66f, 0.42f, 0.31f};
const glm::vec3 lip_color{0.50f, 0.16f, 0.16f};
const glm::vec3 inner_lip_color{0.40f, 0.09f, 0.10f};
const glm::vec3 cavity_color{0.16f, 0.035f, 0.04f};
const glm::vec3 hair_color{0.17f, 0.11f, 0.075f};
const glm::vec3 brow_color{0.22f, 0.14f, 0.10f};
const glm::vec3 tooth_color{0.93f, 0.91f, 0.84f};
const glm::vec3 gum_color{0.72f, 0.36f, 0.38f};
const glm::vec3 tongue_color{0.72f, 0.33f, 0.35f};
const glm::vec3 sclera_color{0.92f, 0.90f, 0.87f};
const glm::vec3 iris_color{0.28f, 0.40f, 0.50f};
const glm::vec3 iris_ring_color{0.14f, 0.20f, 0.26f};
const glm::vec3 pupil_color{0.02f, 0.02f, 0.025f};
const glm::vec3 lid_color{0.62f, 0.39f, 0.29f};
const glm::vec3 lash_color{0.10f, 0.07f, 0.06f};

class MeshBuilder {
public:
    std::uint32_t vertex(glm::vec3 p, glm::vec3 c) {
        m_positions.push_back(p);
        m_colors.push_back(c);
        return static_cast<std::uint32_t>(m_positions.size() - 1);
    }
    void triangle(const std::string& group, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        if (a == b || b == c || a == c) return;
        m_groups[group].push_back({a, b, c});
    }
    // Quad a-b-c-d counter-clockwise seen from outside, split along a-c
    // (or along b-d with `other_diagonal`, for mirror-symmetric meshes).
    void quad(const std::string& group, std::uint32_t a, std::uint32_t b, std::uint32_t c,
              std::uint32_t d, bool other_diagonal = false) {
        if (other_diagonal) {
            triangle(group, a, b, d);
            triangle(group, b, c, d);
        } else {
            triangle(group, a, b, c);
            triangle(group, a, c, d);
        }
    }
    std::size_t triangles() const {
        std::size_t n = 0;
        for (const auto& [name, tris] : m_groups) n += tris.size();
        return n;
    }
    std::string obj(const std::string& header) const {
        std::string out = header;
        out.reserve(m_positions.size() * 48 + triangles() * 24);
        for (std::size_t i = 0; i < m_positions.size(); ++i) {
            const auto& p = m_positions[i];
            const auto& c = m_colors[i];
            out += fmt::format("v {:.3f} {:.3f} {:.3f} {:.3f} {:.3f} {:.3f}\n", p.x, p.y, p.z, c.x, c.y, c.z);
        }
        for (const auto& [name, tris] : m_groups) {
            out += "g " + name + "\n";
            for (const auto& t : tris) out += fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        return out;
    }
    const glm::vec3& position(std::uint32_t i) const { return m_positions[i]; }
    std::size_t vertex_count() const { return m_positions.size(); }

private:
    std::vector<glm::vec3> m_positions;
    std::vector<glm::vec3> m_colors;
    std::map<std::string, std::vector<std::array<std::uint32_t, 3>>> m_groups;
};

// ---- The skull: a superellipsoid whose radii vary with direction. ----
float skull_radius(glm::vec3 d) {
    // Narrower toward the chin, but not to a point: the jaw keeps its width
    // down to the gonial angles.
    const float rx = 73.0f - 11.0f * smoothstep(-0.2f, -0.9f, d.y);
    float rz = d.z > 0 ? 93.0f : 101.0f;
    if (d.z > 0) rz *= 1.0f - 0.10f * smoothstep(-0.45f, -0.95f, d.y);
    const float ry = d.y > 0 ? 112.0f : 116.0f;
    const float p = 2.4f;
    const float h = std::pow(std::pow(std::abs(d.x) / rx, p) + std::pow(std::abs(d.z) / rz, p), 1.0f / p);
    return 1.0f / std::sqrt(h * h + (d.y / ry) * (d.y / ry));
}

// Face layout (mm).
constexpr float eye_x = 31.0f, eye_y = 8.0f;
constexpr float nose_tip_y = -28.0f, nose_base_y = -38.0f;
constexpr float mouth_tilt = 0.64f;
constexpr float mouth_half_width = 23.0f;  // at the lip contact  // angle of the mouth axis below the horizontal (rad)

// Forward relief of the nose (mm). The dorsum rises from the nasion to the
// tip with a flat-topped cross-section (steep side walls, so the key light
// leaves one side in shade); a rounded lobule at the tip; the columella and
// the underside fall back to the subnasale; the alae are rounded wings
// beside the tip, ringed by the alar crease; the nostrils are hollows in the
// underside either side of the columella.
float nose_relief(float x, float y) {
    const float ax = std::abs(x);
    float h = 0.0f;
    // Dorsum: height above the face and half-width along its length.
    const float t = smoothstep(eye_y + 4.0f, nose_tip_y + 2.0f, y);
    float ridge = 0.0f;
    if (y > nose_tip_y) ridge = 1.5f * smoothstep(eye_y + 12.0f, eye_y + 3.0f, y) + 17.5f * std::pow(t, 1.15f);
    else ridge = 19.0f * (1.0f - smoothstep(nose_tip_y, nose_base_y - 0.5f, y));
    const float width = 6.5f + 3.5f * t + 2.0f * smoothstep(nose_tip_y, nose_base_y, y);
    h += ridge * std::exp(-std::pow(ax / width, 2.6f));
    // Tip lobule: two domes that merge into one rounded tip.
    h += 5.5f * gauss2(ax - 2.5f, 6.5f, y - (nose_tip_y - 0.5f), 5.5f);
    // Alae: wings beside the tip, behind it, ringed by the alar crease.
    const float ala_x = 12.0f, ala_y = nose_base_y + 5.5f;
    h += 7.5f * gauss2(ax - ala_x, 4.8f, y - ala_y, 4.6f);
    const float r = std::sqrt((ax - ala_x + 1.5f) * (ax - ala_x + 1.5f) + (y - ala_y) * (y - ala_y) * 1.2f);
    const float lateral = smoothstep(ala_x - 4.0f, ala_x + 2.0f, ax + 0.5f * (y - ala_y));
    h -= 3.0f * std::exp(-std::pow((r - 7.0f) / 1.8f, 2.0f)) * lateral;
    // Nostrils: hollows in the underside beside the columella.
    h -= 3.0f * gauss2(ax - 6.0f, 2.4f, y - (nose_base_y + 2.0f), 2.0f);
    return h;
}

// How dark the nose's hollows look in the skin colour (0 none, 1 full):
// nostrils, the shade under the tip, and the alar crease.
float nose_shade(float x, float y) {
    const float ax = std::abs(x);
    const float ala_x = 12.0f, ala_y = nose_base_y + 5.5f;
    const float r = std::sqrt((ax - ala_x + 1.5f) * (ax - ala_x + 1.5f) + (y - ala_y) * (y - ala_y) * 1.2f);
    const float lateral = smoothstep(ala_x - 4.0f, ala_x + 2.0f, ax + 0.5f * (y - ala_y));
    float s = 0.85f * gauss2(ax - 6.0f, 2.6f, y - (nose_base_y + 1.8f), 1.7f);
    s = std::max(s, 0.15f * std::exp(-std::pow((r - 7.2f) / 1.4f, 2.0f)) * lateral);
    return std::min(s, 1.0f);
}

// Forward relief of the face: nose, brows, eye sockets, cheeks, chin.
float face_relief(float x, float y, float mouth_y) {
    const float ax = std::abs(x);
    float h = nose_relief(x, y);
    h -= 7.0f * gauss2(ax - eye_x, 16.0f, y - eye_y, 11.0f);             // eye sockets
    h += 4.0f * gauss2(ax - 27.0f, 22.0f, y - (eye_y + 16.0f), 7.0f);    // brow ridge
    h += 5.0f * gauss2(ax - 38.0f, 17.0f, y + 18.0f, 15.0f);             // cheeks
    h += 6.5f * gauss2(x, 21.0f, y - (mouth_y - 35.0f), 12.0f);          // chin
    h -= 2.5f * gauss2(x, 15.0f, y - (mouth_y - 17.0f), 5.0f);           // mentolabial sulcus
    h -= 1.2f * gauss2(ax - 5.0f, 2.0f, y - (mouth_y + 17.0f), 6.0f) *
         smoothstep(nose_base_y, nose_base_y - 4.0f, y);                 // philtrum ridges' groove
    return h;
}

// Fullness of the cheeks beside the mouth (mm forward), applied at full
// height even near the lips: it fills the hollow where the protruding mouth
// region meets the cheek, which read as a deep fold from nose to chin.
float cheek_fill(float x, float y, float mouth_y) {
    const float ax = std::abs(x);
    return 4.0f * gauss2(ax - 27.0f, 9.0f, y - (mouth_y + 9.0f), 14.0f) +
           2.0f * gauss2(ax - 36.0f, 9.0f, y - (mouth_y + 2.0f), 16.0f) +
           2.5f * gauss2(ax - 27.0f, 8.0f, y - (mouth_y - 22.0f), 10.0f);
}

struct Generated {
    MeshBuilder mesh;
    nlohmann::json landmarks;
    nlohmann::json articulation;  // landmark vertex indices (articulation.h)
    glm::vec3 mouth{0.0f};
    glm::vec3 left_eye{0.0f};
    glm::vec3 right_eye{0.0f};
    float lid_radius = 0.0f;
};

// The lip/cavity profile for one ring: half-width, half-height (upper, lower)
// and forward offset of the ring relative to the mouth centre at its middle.
struct Ring {
    float s;         // signed distance from the lip contact (mm; < 0 inside)
    float width;
    float h_upper;
    float h_lower;
    float z;         // forward offset at the middle (u = ±90°)
    float z_corner;  // forward offset at the corners
    glm::vec3 color_upper;
    glm::vec3 color_lower;
    std::string group_upper;
    std::string group_lower;
};

void build_skin(Generated& g, const HeadGeneratorSettings& settings) {
    const int nu = settings.azimuth_segments;
    const glm::vec3 f{0.0f, -std::sin(mouth_tilt), std::cos(mouth_tilt)};
    const glm::vec3 e1{1.0f, 0.0f, 0.0f};
    const glm::vec3 e2 = glm::cross(f, e1);  // up along the face
    const glm::vec3 mouth_base = skull_radius(f) * f;
    const float my = mouth_base.y;
    const glm::vec3 mc{0.0f, my, mouth_base.z + face_relief(0.0f, my, my) + 4.0f};
    g.mouth = mc;
    const float arch = 0.010f;  // lips follow the dental arch: z -= arch·x²

    // Rings from the back of the oral cavity to the lip border.
    std::vector<Ring> rings;
    const float cavity[][3] = {{-50, 8, 7},   {-46, 16, 12}, {-40, 22, 16}, {-33, 27, 19},
                               {-26, 30, 21}, {-19, 31, 20}, {-14, 30, 16}, {-10, 27, 10}};
    for (const auto& c : cavity)
        rings.push_back({c[0], c[1], c[2], c[2] * 0.8f, c[0] + 1.0f, c[0] + 1.0f, cavity_color,
                         cavity_color, "upper_cavity", "lower_cavity"});
    // Inner roll of the lips: closed at rest (zero height), wet and darker.
    for (float s : {-7.0f, -4.5f, -2.5f, -1.0f}) {
        const float t = smoothstep(-7.0f, -1.0f, s);
        rings.push_back({s, mouth_half_width - 1.5f * (1.0f - t), 0.0f, 0.0f, s * 0.9f,
                         s * 0.9f, mix3(cavity_color, inner_lip_color, t),
                         mix3(cavity_color, inner_lip_color, t), "upper_inner", "lower_inner"});
    }
    // Vermilion: contact at s = 0, border at s = 9.5 (upper) / 10.5 (lower).
    for (float s : {0.0f, 0.6f, 1.3f, 2.2f, 3.3f, 4.6f, 6.0f, 7.4f, 8.6f, 9.5f}) {
        const float bulge_u = 2.8f * std::sin(0.5f * pi * std::min(s / 3.2f, 1.0f)) - 0.3f * std::max(s - 3.2f, 0.0f);
        const float lip_mix = smoothstep(9.5f, 8.8f, s);
        rings.push_back({s, mouth_half_width + 0.35f * s, 0.9f * s, s, bulge_u + 0.4f, 0.0f,
                         mix3(skin_color, lip_color, lip_mix), mix3(skin_color, lip_color, 1.0f),
                         "upper_lip", "lower_lip"});
    }

    auto ring_point = [&](const Ring& r, float u) {
        const float c = std::cos(u), s = std::sin(u);
        const float h = s >= 0 ? r.h_upper : r.h_lower;
        const float x = r.width * c;
        const float side = std::pow(std::abs(s), 0.6f);
        const float z = r.z_corner + (r.z - r.z_corner) * side - arch * x * x;
        return glm::vec3(x, mc.y + h * s, mc.z + z);
    };

    std::vector<std::vector<std::uint32_t>> grid;
    std::vector<std::string> ring_group_up, ring_group_low;
    // The cavity's back pole.
    const std::uint32_t cavity_pole = g.mesh.vertex({0.0f, mc.y, mc.z - 53.0f}, cavity_color);
    for (const auto& r : rings) {
        std::vector<std::uint32_t> row;
        for (int j = 0; j < nu; ++j) {
            const float u = 2.0f * pi * float(j) / float(nu);
            const bool upper = std::sin(u) > 1e-6f || (std::abs(std::sin(u)) <= 1e-6f);
            glm::vec3 color = upper ? r.color_upper : r.color_lower;
            if (r.group_upper == "upper_lip") {
                // Lower lip vermilion ends at s = 10.5; colour the upper lip by its ring.
                color = std::sin(u) >= 0 ? r.color_upper : lip_color;
            }
            row.push_back(g.mesh.vertex(ring_point(r, u), color));
        }
        grid.push_back(row);
        ring_group_up.push_back(r.group_upper);
        ring_group_low.push_back(r.group_lower);
    }

    // Skin rings: blend from the extrapolated lip profile to the skull surface.
    const int ns = settings.skin_rings;
    const float alpha0 = 0.115f;
    const Ring& border = rings.back();
    for (int k = 0; k < ns; ++k) {
        const float t = float(k + 1) / float(ns + 1);
        const float alpha = alpha0 + (pi - alpha0) * std::pow(t, 1.55f);
        const float blend = smoothstep(alpha0, 0.55f, alpha);
        std::vector<std::uint32_t> row;
        for (int j = 0; j < nu; ++j) {
            const float u = 2.0f * pi * float(j) / float(nu);
            const float cu = std::cos(u), su = std::sin(u);
            // The lip profile continued outward.
            const float s = border.s + (alpha - 0.095f) * 100.0f;
            const float grow = s - border.s;
            const float w = border.width + 0.9f * grow;
            const float h = (su >= 0 ? 1.0f : 1.1f) * s;
            const float side = std::pow(std::abs(su), 0.6f) + (1.0f - std::pow(std::abs(su), 0.6f)) * smoothstep(0.0f, 12.0f, grow);
            const float zl = (border.z - 0.35f * grow) * side -
                             arch * (w * cu) * (w * cu) * (1.0f - smoothstep(0.0f, 30.0f, grow));
            glm::vec3 lip_ext{w * cu, mc.y + h * su, mc.z + zl - 1.5f * smoothstep(0.0f, 8.0f, grow)};
            // The skull point along the ring direction.
            const glm::vec3 d = glm::normalize(std::cos(alpha) * f + std::sin(alpha) * (cu * e1 + su * e2));
            const glm::vec3 skull = skull_radius(d) * d;
            glm::vec3 p = mix3(lip_ext, skull, blend);
            // The relief, evaluated where the point lands (evaluated at the
            // skull point instead, the nose was blended with copies of itself
            // shifted sideways: a dark smear under it). Near the mouth the
            // surface follows the lip profile more than the skull; the nose
            // keeps its full height there all the same.
            const float nose = nose_relief(p.x, p.y);
            const float nose_weight = blend + (1.0f - blend) * smoothstep(nose_base_y - 8.0f, nose_base_y - 2.0f, p.y);
            p.z += smoothstep(0.05f, 0.45f, d.z) *
                   (blend * (face_relief(p.x, p.y, my) - nose) + nose_weight * nose + cheek_fill(p.x, p.y, my));
            // Colour: skin, hair above the hairline, eyebrows.
            glm::vec3 color = skin_color;
            const float hairline = -55.0f + 115.0f * smoothstep(-40.0f, 75.0f, p.z) -
                                   12.0f * smoothstep(30.0f, 60.0f, std::abs(p.x)) * smoothstep(20.0f, 70.0f, p.z);
            const float hair = smoothstep(hairline - 2.0f, hairline + 4.0f, p.y);
            const float brow = std::exp(-std::pow((p.y - (eye_y + 17.0f - 0.05f * std::abs(p.x))) / 3.2f, 2.0f)) *
                               std::exp(-std::pow((std::abs(p.x) - 29.0f) / 15.0f, 4.0f)) *
                               smoothstep(40.0f, 70.0f, p.z);
            color = mix3(color, brow_color, 0.85f * brow);
            color = mix3(color, hair_color, hair);
            // Slight redness on the cheeks and lips' surroundings.
            color = mix3(color, glm::vec3(0.12f, 0.035f, 0.03f), nose_shade(p.x, p.y));  // nostrils, alar crease
            color = mix3(color, glm::vec3(0.70f, 0.38f, 0.30f),
                         0.5f * gauss2(p.x, 9.0f, p.y - nose_tip_y, 7.0f));  // the tip slightly redder
            color = mix3(color, glm::vec3(0.68f, 0.36f, 0.28f),
                         0.35f * gauss2(std::abs(p.x) - 40.0f, 16.0f, p.y + 22.0f, 14.0f));
            if (hair > 0.0f) p += 3.0f * hair * glm::normalize(p - glm::vec3(0, -10, -5));
            row.push_back(g.mesh.vertex(p, color));
        }
        grid.push_back(row);
        // Groups for the rig: the skin near the mouth above/below the lip line,
        // the lower face that the jaw carries, and the rest.
        ring_group_up.push_back(alpha < 0.75f ? "face_upper" : "skin");
        ring_group_low.push_back(alpha < 0.75f ? "face_lower" : "jaw_skin");
    }
    const std::uint32_t back_pole = g.mesh.vertex(skull_radius(-f) * -f, hair_color);

    // Triangulate: ring r (inner) to ring r+1 (outer), counter-clockwise seen from outside.
    auto group_of = [&](std::size_t r, int j) {
        const float um = 2.0f * pi * (float(j) + 0.5f) / float(nu);
        const bool upper = std::sin(um) >= 0.0f;
        std::string name = upper ? ring_group_up[r] : ring_group_low[r];
        if (name == "jaw_skin") {
            // Only the lower face in front of the ears goes with the jaw.
            const glm::vec3 p = g.mesh.position(grid[r][static_cast<std::size_t>(j)]);
            if (!(p.y < my + 5.0f && p.z > 5.0f && p.y > my - 75.0f)) name = "skin";
        }
        return name;
    };
    for (int j = 0; j < nu; ++j) {
        const int jn = (j + 1) % nu;
        // Cavity pole fan: looking from inside the cavity outward is "outside".
        g.mesh.triangle(std::sin(2.0f * pi * (float(j) + 0.5f) / float(nu)) >= 0 ? "upper_cavity" : "lower_cavity",
                        cavity_pole, grid[0][static_cast<std::size_t>(j)], grid[0][static_cast<std::size_t>(jn)]);
    }
    for (std::size_t r = 0; r + 1 < grid.size(); ++r) {
        for (int j = 0; j < nu; ++j) {
            const auto jj = static_cast<std::size_t>(j), jn = static_cast<std::size_t>((j + 1) % nu);
            // Diagonals mirrored across the midline (x = 0), so both halves of
            // the face get the same vertex normals.
            const bool right_half = std::cos(2.0f * pi * (float(j) + 0.5f) / float(nu)) < 0.0f;
            g.mesh.quad(group_of(r + 1, j), grid[r][jj], grid[r + 1][jj], grid[r + 1][jn], grid[r][jn], right_half);
        }
    }
    for (int j = 0; j < nu; ++j) {
        const auto jj = static_cast<std::size_t>(j), jn = static_cast<std::size_t>((j + 1) % nu);
        g.mesh.triangle("skin", grid.back()[jn], grid.back()[jj], back_pole);
    }

    // Articulation landmarks. The contact ring (s = 0) holds the lips' inner
    // edges: its upper-half vertex at azimuth u pairs with the lower-half one
    // at −u (the same x at rest); the corners (u = 0, π) are shared.
    std::size_t contact_ring = 0;
    while (rings[contact_ring].s != 0.0f) ++contact_ring;
    std::size_t front_ring = contact_ring;  // the most forward vermilion ring at the midline
    for (std::size_t r = contact_ring; r < rings.size(); ++r)
        if (rings[r].z > rings[front_ring].z) front_ring = r;
    const auto half = static_cast<std::size_t>(nu / 2), quarter = static_cast<std::size_t>(nu / 4);
    nlohmann::json upper = nlohmann::json::array(), lower = nlohmann::json::array(), surface = nlohmann::json::array();
    for (std::size_t j = half - 1; j >= 1; --j) {
        upper.push_back(grid[contact_ring][j]);
        lower.push_back(grid[contact_ring][static_cast<std::size_t>(nu) - j]);
    }
    // The lower lip's inner roll and vermilion near the midline: what meets
    // the upper incisors in /f v/.
    for (std::size_t r = contact_ring - 4; r <= front_ring + 2; ++r)
        for (std::size_t j = half + 1; j < static_cast<std::size_t>(nu); ++j)
            if (std::abs(g.mesh.position(grid[r][j]).x) <= 15.0f) surface.push_back(grid[r][j]);
    g.articulation["upper_lip_contour"] = upper;
    g.articulation["lower_lip_contour"] = lower;
    g.articulation["mouth_corners"] = {grid[contact_ring][0], grid[contact_ring][half]};
    g.articulation["upper_lip_point"] = grid[front_ring][quarter];
    g.articulation["lower_lip_point"] = grid[front_ring][half + quarter];
    g.articulation["lower_lip_surface"] = surface;
    g.articulation["up"] = {0.0, 1.0, 0.0};
    g.articulation["forward"] = {0.0, 0.0, 1.0};

    g.landmarks["mouth_middle"] = {0.0, mc.y, mc.z};
    const glm::vec3 corner = ring_point(rings[rings.size() - 10], 0.0f);
    g.landmarks["mouth_left"] = {corner.x, corner.y, corner.z};
    g.landmarks["mouth_right"] = {-corner.x, corner.y, corner.z};
}

// Depth of the face surface at (x, y) by bisection along z on the skull plus relief.
float face_z(float x, float y, float mouth_y) {
    float lo = 0.0f, hi = 140.0f;
    for (int it = 0; it < 60; ++it) {
        const float z = 0.5f * (lo + hi);
        const glm::vec3 p{x, y, z};
        const float r = skull_radius(glm::normalize(p));
        if (glm::length(p) < r) lo = z;
        else hi = z;
    }
    return lo + face_relief(x, y, mouth_y);
}

// A UV sphere with its pole along +z, with rings at the given polar angles
// (duplicated at colour edges so the iris has a crisp rim).
void build_eye(Generated& g, glm::vec3 center, float radius) {
    const int na = 40;
    struct R {
        float theta;
        glm::vec3 color;
    };
    const float pupil = 0.19f, iris = 0.50f;
    const std::vector<R> rings{{0.0f, pupil_color},        {0.10f, pupil_color},    {pupil, pupil_color},
                               {pupil, iris_color},        {0.30f, iris_color},     {0.42f, iris_color},
                               {iris - 0.02f, iris_ring_color}, {iris, iris_ring_color}, {iris, sclera_color},
                               {0.70f, sclera_color},      {0.95f, sclera_color},   {1.25f, sclera_color},
                               {1.6f, sclera_color},       {2.0f, sclera_color},    {2.5f, sclera_color},
                               {pi, sclera_color}};
    std::vector<std::vector<std::uint32_t>> grid;
    for (const auto& r : rings) {
        std::vector<std::uint32_t> row;
        const bool pole = r.theta == 0.0f || r.theta == pi;
        const int n = pole ? 1 : na;
        for (int j = 0; j < n; ++j) {
            const float phi = 2.0f * pi * float(j) / float(na);
            // Iris bulges slightly (cornea) so it catches the light.
            const float rr = radius + (r.theta < iris ? 0.35f * std::cos(r.theta / iris * 0.5f * pi) : 0.0f);
            const glm::vec3 d{std::sin(r.theta) * std::cos(phi), std::sin(r.theta) * std::sin(phi), std::cos(r.theta)};
            row.push_back(g.mesh.vertex(center + rr * d, r.color));
        }
        grid.push_back(row);
    }
    for (std::size_t r = 0; r + 1 < grid.size(); ++r) {
        for (int j = 0; j < na; ++j) {
            const auto jj = static_cast<std::size_t>(j), jn = static_cast<std::size_t>((j + 1) % na);
            const auto a0 = grid[r].size() == 1 ? grid[r][0] : grid[r][jj];
            const auto a1 = grid[r].size() == 1 ? grid[r][0] : grid[r][jn];
            const auto b0 = grid[r + 1].size() == 1 ? grid[r + 1][0] : grid[r + 1][jj];
            const auto b1 = grid[r + 1].size() == 1 ? grid[r + 1][0] : grid[r + 1][jn];
            // theta grows inward → outward-facing winding is (a0, b0, b1, a1).
            g.mesh.quad("eyes", a0, b0, b1, a1);
        }
    }
}

// Eyelids: a shell around the eyeball with an almond-shaped opening; the
// upper lid is its own group so the blink channel can rotate it down.
void build_lids(Generated& g, glm::vec3 center, float radius) {
    const int naz = 36, nel = 10;
    const float az_max = 1.75f;
    auto point = [&](float az, float el) {
        return center + radius * glm::vec3(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
    };
    for (int lid = 0; lid < 2; ++lid) {
        const bool upper = lid == 0;
        std::vector<std::vector<std::uint32_t>> grid;
        for (int i = 0; i <= nel; ++i) {
            std::vector<std::uint32_t> row;
            const float t = float(i) / float(nel);
            for (int j = 0; j <= naz; ++j) {
                const float az = -az_max + 2.0f * az_max * float(j) / float(naz);
                const float edge = upper ? 0.44f * std::cos(az * 0.86f) - 0.02f : -0.30f * std::cos(az * 0.86f) + 0.02f;
                const float far = upper ? 1.55f : -1.1f;
                const float el = edge + (far - edge) * t;
                glm::vec3 c = i == 0 ? lash_color : (i == 1 ? mix3(lid_color, lash_color, upper ? 0.5f : 0.2f) : lid_color);
                // A lid fold: the upper lid's skin swells slightly above the edge.
                const float rr = radius + (upper ? 0.6f * std::sin(std::min(t * 3.0f, 1.0f) * pi) : 0.3f * t);
                glm::vec3 p = center + (rr / radius) * (point(az, el) - center);
                row.push_back(g.mesh.vertex(p, c));
            }
            grid.push_back(row);
        }
        const std::string group = upper ? "upper_lids" : "lower_lids";
        for (int i = 0; i < nel; ++i)
            for (int j = 0; j < naz; ++j) {
                const auto ii = static_cast<std::size_t>(i), jj = static_cast<std::size_t>(j);
                if (upper) g.mesh.quad(group, grid[ii][jj], grid[ii][jj + 1], grid[ii + 1][jj + 1], grid[ii + 1][jj]);
                else g.mesh.quad(group, grid[ii][jj], grid[ii + 1][jj], grid[ii + 1][jj + 1], grid[ii][jj + 1]);
            }
    }
}

// A swept closed profile along a curve: rows of `profile` points.
void sweep(Generated& g, const std::string& group, const std::vector<std::vector<glm::vec3>>& rows,
           const std::vector<std::vector<glm::vec3>>& colors, bool close_ends) {
    std::vector<std::vector<std::uint32_t>> ids;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        std::vector<std::uint32_t> row;
        for (std::size_t k = 0; k < rows[i].size(); ++k) row.push_back(g.mesh.vertex(rows[i][k], colors[i][k]));
        ids.push_back(row);
    }
    const std::size_t m = rows.front().size();
    for (std::size_t i = 0; i + 1 < ids.size(); ++i)
        for (std::size_t k = 0; k < m; ++k)
            g.mesh.quad(group, ids[i][k], ids[i + 1][k], ids[i + 1][(k + 1) % m], ids[i][(k + 1) % m]);
    if (close_ends) {
        for (int end = 0; end < 2; ++end) {
            const auto& row = end == 0 ? rows.front() : rows.back();
            glm::vec3 c{0.0f};
            for (const auto& p : row) c += p;
            c /= float(row.size());
            const auto& id = end == 0 ? ids.front() : ids.back();
            const std::uint32_t centre = g.mesh.vertex(c, colors.front().front());
            for (std::size_t k = 0; k < m; ++k) {
                if (end == 0) g.mesh.triangle(group, centre, id[(k + 1) % m], id[k]);
                else g.mesh.triangle(group, centre, id[k], id[(k + 1) % m]);
            }
        }
    }
}

// A row of teeth along the dental arch z = z0 − k·x²; `edge_y` is the
// incisal edge, `gum_y` the gum line, `root_y` where the shape ends in the gum.
// Returns the incisal edge's vertices across the four incisors (|x| ≤ 15.2 mm).
nlohmann::json build_teeth(Generated& g, const std::string& group, float z0, float edge_y, float gum_y, float root_y,
                           float thickness) {
    const int na = 56, np = 20;
    const float half_width = 24.0f, k = 0.026f;
    const float boundaries[] = {0.0f, 8.6f, 15.2f, 21.5f};
    std::vector<std::vector<glm::vec3>> rows, colors;
    const float yc = 0.5f * (edge_y + root_y), hy = 0.5f * std::abs(root_y - edge_y);
    for (int i = 0; i <= na; ++i) {
        const float x = -half_width + 2.0f * half_width * float(i) / float(na);
        const float z = z0 - k * x * x;
        glm::vec3 tangent = glm::normalize(glm::vec3(1.0f, 0.0f, -2.0f * k * x));
        glm::vec3 normal = glm::normalize(glm::cross(tangent, glm::vec3(0, 1, 0)));  // outward (front)
        normal = -normal;
        if (normal.z < 0) normal = -normal;
        // Gaps between teeth: shallow grooves.
        float gap = 1e9f;
        for (float b : boundaries) gap = std::min({gap, std::abs(std::abs(x) - b)});
        const float groove = std::exp(-gap * gap / 0.5f);
        // Each tooth's edge is slightly rounded at its corners.
        std::vector<glm::vec3> row, crow;
        for (int p = 0; p < np; ++p) {
            const float a = 2.0f * pi * float(p) / float(np);
            const float ca = std::cos(a), sa = std::sin(a);
            const float e = 0.25f;  // superellipse exponent (boxy)
            const float py = std::copysign(std::pow(std::abs(sa), e), sa) * hy;
            const float pn = std::copysign(std::pow(std::abs(ca), e), ca) * 0.5f * thickness * (1.0f - 0.35f * groove);
            float y = yc + py;
            const bool edge_side = (edge_y < root_y) ? (y < yc) : (y > yc);
            if (edge_side) y -= (edge_y < root_y ? -1.0f : 1.0f) * 0.8f * groove;
            const glm::vec3 pos = glm::vec3(x, y, z) + normal * pn;
            const float gum = (edge_y < root_y) ? smoothstep(gum_y - 0.6f, gum_y + 0.6f, y)
                                                : smoothstep(gum_y + 0.6f, gum_y - 0.6f, y);
            glm::vec3 c = mix3(tooth_color, tooth_color * 0.72f, 0.7f * groove);
            c = mix3(c, gum_color, gum);
            row.push_back(pos);
            crow.push_back(c);
        }
        rows.push_back(row);
        colors.push_back(crow);
    }
    // sweep() adds the rows' vertices in order; the edge is the profile point
    // at a = 3π/2 (upper teeth, edge below) or π/2 (lower teeth, edge above).
    const auto first = static_cast<std::uint32_t>(g.mesh.vertex_count());
    const std::size_t edge_point = static_cast<std::size_t>(edge_y < root_y ? 3 * np / 4 : np / 4);
    nlohmann::json edge = nlohmann::json::array();
    for (int i = 0; i <= na; ++i)
        if (std::abs(rows[static_cast<std::size_t>(i)][edge_point].x) <= 15.2f)
            edge.push_back(first + static_cast<std::uint32_t>(static_cast<std::size_t>(i) * static_cast<std::size_t>(np) + edge_point));
    sweep(g, group, rows, colors, true);
    return edge;
}

void build_tongue(Generated& g, glm::vec3 c, glm::vec3 radii) {
    const int nt = 14, np = 28;
    std::vector<std::vector<glm::vec3>> rows, colors;
    for (int i = 1; i < nt; ++i) {
        const float th = pi * float(i) / float(nt);  // from the tip (front) backward
        std::vector<glm::vec3> row, crow;
        for (int p = 0; p < np; ++p) {
            const float a = 2.0f * pi * float(p) / float(np);
            glm::vec3 d{std::sin(th) * std::cos(a), std::sin(th) * std::sin(a), std::cos(th)};
            if (d.y > 0) d.y *= 1.0f - 0.25f * std::exp(-d.x * d.x * 30.0f);  // median groove
            row.push_back(c + d * radii);
            crow.push_back(mix3(tongue_color, tongue_color * 0.75f, 0.5f * (1.0f - std::cos(th)) * 0.6f));
        }
        rows.push_back(row);
        colors.push_back(crow);
    }
    // Orientation: rows go backward, profile counter-clockwise seen from the front.
    std::reverse(rows.begin(), rows.end());
    std::reverse(colors.begin(), colors.end());
    sweep(g, "tongue", rows, colors, true);
}

void build_ears(Generated& g) {
    for (int side = -1; side <= 1; side += 2) {
        const glm::vec3 c{float(side) * 70.0f, -8.0f, -8.0f};
        const int nt = 18, np = 28;
        std::vector<std::vector<glm::vec3>> rows, colors;
        for (int i = 1; i < nt; ++i) {
            const float th = pi * float(i) / float(nt);
            std::vector<glm::vec3> row, crow;
            for (int p = 0; p < np; ++p) {
                const float a = 2.0f * pi * float(p) / float(np);
                // Ellipsoid: thin across x, tall in y; flared outward at its back rim.
                const glm::vec3 d{std::cos(th), std::sin(th) * std::cos(a), std::sin(th) * std::sin(a)};
                glm::vec3 q{d.x * 6.0f, d.y * 30.0f, d.z * 17.0f};
                q.x += 5.0f * (0.5f + 0.5f * d.z) * (d.y > -0.6f ? 1.0f : 0.5f);
                q.x -= 3.0f * std::exp(-(d.y * d.y + d.z * d.z) * 4.0f) * (d.x > 0 ? 1.0f : 0.0f);  // concha
                q.x *= float(side);
                row.push_back(c + q);
                crow.push_back(mix3(skin_color, glm::vec3(0.66f, 0.36f, 0.28f), 0.5f));
            }
            rows.push_back(row);
            colors.push_back(crow);
        }
        if (side < 0) {
            std::reverse(rows.begin(), rows.end());
            std::reverse(colors.begin(), colors.end());
        }
        sweep(g, "ears", rows, colors, true);
    }
}

// The neck: an elliptic tube from inside the head down to the shoulders,
// about as wide as the jaw (~116 mm, an adult's ~37 cm circumference), a
// little narrower at mid-height, widening into the trapezius slope below.
void build_neck(Generated& g) {
    const int na = 56, nr = 14;
    std::vector<std::vector<glm::vec3>> rows, colors;
    for (int i = 0; i <= nr; ++i) {
        const float t = float(i) / float(nr);
        std::vector<glm::vec3> row, crow;
        for (int p = 0; p < na; ++p) {
            const float a = 2.0f * pi * float(p) / float(na);
            // The top ends inside the head: at the back and sides high up, in
            // front under the jaw, below the oral cavity even with the jaw
            // open (a neck reaching higher showed through the open mouth).
            const float y_top = -45.0f - 50.0f * smoothstep(0.72f, 0.97f, std::sin(a));
            const float y = y_top + (-280.0f - y_top) * t;
            const float half_width = 58.0f - 3.0f * smoothstep(-60.0f, -140.0f, y) +
                                     95.0f * std::pow(smoothstep(-150.0f, -280.0f, y), 1.6f);
            const float half_depth = 46.0f + 5.0f * smoothstep(-95.0f, -135.0f, y) +
                                     6.0f * smoothstep(-170.0f, -280.0f, y);
            const float zc = -18.0f + 4.0f * smoothstep(-95.0f, -170.0f, y);
            row.push_back({half_width * std::cos(a), y, zc + half_depth * std::sin(a)});
            crow.push_back(skin_color * (0.97f - 0.05f * t));
        }
        rows.push_back(row);
        colors.push_back(crow);
    }
    // Profile runs counter-clockwise seen from above; rows go downward.
    std::vector<std::vector<glm::vec3>> rrows(rows.rbegin(), rows.rend());
    std::vector<std::vector<glm::vec3>> rcolors(colors.rbegin(), colors.rend());
    sweep(g, "neck", rrows, rcolors, false);
}

nlohmann::json vec(glm::vec3 v) { return {v.x, v.y, v.z}; }

nlohmann::json make_rig(const Generated& g) {
    using nlohmann::json;
    const glm::vec3 mc = g.mouth;
    const glm::vec3 hinge{0.0f, -12.0f, 0.0f};
    auto ellipsoid = [](glm::vec3 c, glm::vec3 r, float inner) {
        return json{{"ellipsoid", {{"center", vec(c)}, {"radii", vec(r)}, {"inner", inner}}}};
    };
    const json upper_lip = {{"groups", {"upper_lip", "upper_inner", "face_upper"}},
                            {"smooth", 4},
                            {"falloff", {ellipsoid(mc, {36, 26, 40}, 0.35f)}}};
    const json upper_lip_mid = {{"groups", {"upper_lip", "upper_inner", "face_upper"}},
                                {"smooth", 4},
                                {"falloff", {ellipsoid(mc, {27, 24, 40}, 0.25f)}}};
    const json lower_lip = {{"groups", {"lower_lip", "lower_inner", "face_lower"}},
                            {"smooth", 4},
                            {"falloff", {ellipsoid(mc, {36, 28, 40}, 0.35f)}}};
    const json lower_lip_mid = {{"groups", {"lower_lip", "lower_inner", "face_lower"}},
                                {"smooth", 4},
                                {"falloff", {ellipsoid(mc, {27, 26, 40}, 0.25f)}}};
    const json lips = {{"groups", {"upper_lip", "upper_inner", "face_upper", "lower_lip", "lower_inner", "face_lower"}},
                       {"smooth", 3},
                       {"falloff", {ellipsoid(mc, {40, 30, 40}, 0.4f)}}};
    // The jaw carries the lower face fully; the mouth corners go half way, so
    // near the corners the lower lip gives up half and the upper lip takes half.
    const json jaw_ellipsoid = ellipsoid({0.0f, mc.y - 25.0f, 45.0f}, {100, 80, 95}, 0.55f);
    json corner_band = {ellipsoid(mc, {mouth_half_width * 0.95f, 14, 100}, 0.45f),
                        ellipsoid(mc, {mouth_half_width + 18.0f, 22, 100}, 0.6f)};
    corner_band[0]["ellipsoid"]["invert"] = true;
    const json jaw = json::array(
        {{{"groups", {"lower_lip", "lower_inner", "lower_cavity", "lower_teeth", "tongue", "face_lower", "jaw_skin"}},
          {"smooth", 6},
          {"falloff", {jaw_ellipsoid}}},
         {{"groups", {"lower_lip", "lower_inner", "lower_cavity", "face_lower"}},
          {"smooth", 2},
          {"scale", -0.5},
          {"falloff", corner_band}},
         {{"groups", {"upper_lip", "upper_inner", "upper_cavity", "face_upper"}},
          {"smooth", 2},
          {"scale", 0.5},
          {"falloff", corner_band}}});
    auto corner = [&](float side) {
        return json{{"groups", {"upper_lip", "upper_inner", "face_upper", "lower_lip", "lower_inner", "face_lower"}},
                    {"smooth", 3},
                    {"falloff", {ellipsoid({side * 27.0f, mc.y, mc.z - 6.0f}, {24, 20, 30}, 0.2f)}}};
    };
    json transforms = json::array();
    auto add = [&](const std::string& channel, json op, const json& region, const std::string& note) {
        op["channel"] = channel;
        op["region"] = region;
        op["note"] = note;
        transforms.push_back(op);
    };
    add("lip_rounding", {{"scale", {{"pivot", vec(mc)}, {"factor", {-0.55, 0.05, 0.0}}}}}, lips,
        "narrow the mouth toward its centre (negative spreads it)");
    add("lip_rounding", {{"translate", {0.0, 0.0, 5.0}}}, lips, "rounded lips protrude");
    add("upper_lip_retraction", {{"translate", {0.0, 0.8, -4.0}}}, upper_lip, "upper lip back (negative: protruded)");
    add("upper_lip_raise", {{"translate", {0.0, 5.0, 0.5}}}, upper_lip_mid, "upper lip up, baring the upper teeth");
    add("lower_lip_retraction", {{"translate", {0.0, 3.5, -6.5}}}, lower_lip,
        "lower lip back and up, under the upper incisors for /f v/");
    add("lower_lip_depression", {{"translate", {0.0, -6.0, 0.5}}}, lower_lip_mid, "lower lip down from the jaw");
    add("mouth_corner_stretch_left", {{"translate", {5.0, 0.6, -2.5}}}, corner(1.0f), "left corner outward");
    add("mouth_corner_stretch_right", {{"translate", {-5.0, 0.6, -2.5}}}, corner(-1.0f), "right corner outward");
    add("jaw_thrust", {{"translate", {0.0, 0.0, 4.0}}}, jaw, "jaw forward");
    add("jaw_shift", {{"translate", {4.0, 0.0, 0.0}}}, jaw, "jaw to the speaker's left");
    add("jaw_rotation", {{"rotate", {{"pivot", vec(hinge)}, {"axis", {1.0, 0.0, 0.0}}, {"angle_deg", 15.0}}}}, jaw,
        "open the jaw about the condylar hinge (1 = ~20 mm incisor gap)");
    for (const auto* eye : {&g.left_eye, &g.right_eye}) {
        add("blink", {{"rotate", {{"pivot", vec(*eye)}, {"axis", {1.0, 0.0, 0.0}}, {"angle_deg", 46.0}}}},
            json{{"groups", {"upper_lids"}}, {"falloff", {ellipsoid(*eye, {20, 20, 20}, 0.9f)}}},
            "close the upper eyelid");
    }
    return transforms;
}

}  // namespace

void generate_head(const std::filesystem::path& obj_path, const std::filesystem::path& rig_path,
                   const HeadGeneratorSettings& settings) {
    Generated g;
    build_skin(g, settings);
    const float my = g.mouth.y;
    const float eye_radius = 12.0f;
    for (int side = -1; side <= 1; side += 2) {
        const float x = float(side) * eye_x;
        const glm::vec3 c{x, eye_y, face_z(x, eye_y, my) - eye_radius + 4.0f};
        build_eye(g, c, eye_radius);
        build_lids(g, c, eye_radius + 0.7f);
        (side > 0 ? g.left_eye : g.right_eye) = c;
    }
    const glm::vec3 mc = g.mouth;
    // Upper incisal edge 1.5 mm below the lip line, lower incisors behind it (overbite).
    g.articulation["upper_incisor_edge"] =
        build_teeth(g, "upper_teeth", mc.z - 8.2f, mc.y - 1.5f, mc.y + 7.5f, mc.y + 11.0f, 4.4f);
    g.articulation["lower_incisor_edge"] =
        build_teeth(g, "lower_teeth", mc.z - 11.6f, mc.y + 0.3f, mc.y - 7.0f, mc.y - 11.0f, 4.0f);
    build_tongue(g, {0.0f, mc.y - 8.0f, mc.z - 32.0f}, {19.0f, 6.5f, 19.0f});
    build_ears(g);
    build_neck(g);

    g.landmarks["left_eye"] = vec(g.left_eye);
    g.landmarks["right_eye"] = vec(g.right_eye);
    g.landmarks["nose_bottom"] = {0.0, nose_base_y, face_z(0.0f, nose_base_y, my)};
    g.landmarks["iris_diameter"] = 2.0 * eye_radius * std::sin(0.5);
    g.landmarks["head_center"] = {0.0, -35.0, 0.0};  // the default camera target: the face, chin and neck in view
    g.landmarks["head_height"] = 230.0;

    nlohmann::json rig;
    rig["format"] = "avsi-rig";
    rig["version"] = 1;
    rig["units"] = "mm";
    rig["mesh"] = obj_path.filename().string();
    rig["generator"] = "avsi::stimuli::generate_head (stimuli/src/head_generator.cpp), scripts/make-head";
    rig["landmarks"] = g.landmarks;
    rig["articulation"] = g.articulation;
    // Rounding narrows and protrudes the lips; it does not open them (the
    // opening of /uw w/ is the jaw's and the lips'), so a bilabial closes in
    // any rounding context. Where the lips' edges would pass through each
    // other they flatten against each other instead.
    rig["lip_contact"] = {{"upper", {{"groups", {"upper_lip", "upper_inner"}}}},
                          {"lower", {{"groups", {"lower_lip", "lower_inner"}}}},
                          {"reach_mm", 6.0}};
    rig["transforms"] = make_rig(g);

    const std::string header = fmt::format(
        "# avsi built-in talking head, generated by stimuli/src/head_generator.cpp (scripts/make-head).\n"
        "# Units: mm; x = speaker's left, y = up, z = forward. Vertex colours are linear RGB.\n"
        "# {} triangles.\n",
        g.mesh.triangles());
    write_text_file(obj_path, g.mesh.obj(header));
    write_text_file(rig_path, rig.dump(2) + "\n");
}

}  // namespace avsi::stimuli
