// The GL drawing of the head: one vertex buffer (positions and normals
// updated per frame; colours, materials and texture coordinates static), a
// texture (the rig's, or white), and a lighting model for skin: three
// directional lights (key, fill, rim) and a sky/ground ambient; diffuse
// light wrapped past the terminator with the wrapped part tinted red, as
// light scattered under the skin shows (the "wrap lighting" approximation
// of subsurface scattering, Green 2004, GPU Gems ch. 16); a soft Blinn-Phong
// highlight (Blinn 1977) with Schlick's Fresnel term. Evaluated per vertex
// (default, fast on llvmpipe) or per pixel; glossy materials (the eyes'
// cornea highlight) always per pixel. Alpha-blended materials (hair, brows,
// lashes) are drawn after the opaque ones, back to front, without depth
// writes. A region mode writes the mesh group of each triangle
// (gl_PrimitiveID into a texture buffer) for tests.
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "avsi/core/error.h"
#include "avsi/stimuli/renderer.h"
#include "gl_api.h"

namespace avsi::stimuli {

namespace detail {

void Gl::load(GlProcLoader loader) {
#define AVSI_GL_LOAD(type, name)                                                    \
    name = reinterpret_cast<type>(loader(#name));                                   \
    if (name == nullptr) throw std::runtime_error("OpenGL function not available: " #name);
    AVSI_GL_FUNCTIONS(AVSI_GL_LOAD)
#undef AVSI_GL_LOAD
}

}  // namespace detail

CameraView camera_view_from_name(const std::string& name) {
    if (name == "front") return CameraView::Front;
    if (name == "three-quarter") return CameraView::ThreeQuarter;
    throw InputError(Diagnostic{"", 0, 0, "camera",
                                "expected \"front\" or \"three-quarter\", got \"" + name + "\""});
}

namespace {

// Attributes: position, normal (per frame); colour (texture multiplier),
// material (specular, shininess, wrap), texture coordinates (static).
#define AVSI_ATTRIBUTES                                                               \
    "layout(location = 0) in vec3 a_position;\n"                                      \
    "layout(location = 1) in vec3 a_normal;\n"                                        \
    "layout(location = 2) in vec3 a_color;\n"                                         \
    "layout(location = 3) in vec3 a_material;\n"                                      \
    "layout(location = 4) in vec2 a_uv;\n"                                            \
    "uniform mat4 u_view_proj;\n"

// The lighting (see the file comment): diffuse and specular light at a point.
#define AVSI_LIGHTING                                                                 \
    "uniform vec3 u_eye;\n"                                                           \
    "uniform vec3 u_light_dir[3];\n"                                                  \
    "uniform vec3 u_light_color[3];\n"                                                \
    "uniform vec3 u_sky;\n"                                                           \
    "uniform vec3 u_ground;\n"                                                        \
    "uniform vec3 u_scatter;\n"                                                       \
    "void light(vec3 p, vec3 n_in, vec3 material, out vec3 diffuse, out vec3 specular) {\n" \
    "    vec3 n = normalize(n_in);\n"                                                 \
    "    vec3 v = normalize(u_eye - p);\n"                                            \
    "    diffuse = mix(u_ground, u_sky, 0.5 + 0.5 * n.y);\n"                          \
    "    specular = vec3(0.0);\n"                                                     \
    "    for (int i = 0; i < 3; ++i) {\n"                                             \
    "        vec3 l = u_light_dir[i];\n"                                              \
    "        float ndl = dot(n, l);\n"                                                \
    "        float lambert = max(ndl, 0.0);\n"                                        \
    "        float wrapped = max((ndl + material.z) / (1.0 + material.z), 0.0);\n"    \
    "        diffuse += u_light_color[i] * (vec3(lambert) + u_scatter * (wrapped - lambert));\n" \
    "        if (ndl > 0.0) {\n"                                                      \
    "            vec3 h = normalize(l + v);\n"                                        \
    "            float fresnel = 0.04 + 0.96 * pow(1.0 - max(dot(v, h), 0.0), 5.0);\n" \
    "            specular += u_light_color[i] * (material.x * (0.6 + 0.4 * fresnel) *\n" \
    "                        pow(max(dot(n, h), 0.0), material.y) * lambert);\n"     \
    "        }\n"                                                                     \
    "    }\n"                                                                         \
    "}\n"

// Texture (sRGB, made linear) times the vertex colour; the display gamma.
// Gamma 2 (a square and a square root) stands for sRGB's 2.2: on llvmpipe
// pow() per pixel costs a third of the frame.
#define AVSI_SURFACE                                                                  \
    "uniform sampler2D u_texture;\n"                                                  \
    "uniform float u_alpha_cut;\n"                                                    \
    "vec4 surface(vec2 uv, vec3 color, vec3 diffuse, vec3 specular) {\n"              \
    "    vec4 t = texture(u_texture, uv);\n"                                          \
    "    if (t.a < u_alpha_cut) discard;\n"                                           \
    "    vec3 albedo = t.rgb * t.rgb * color;\n"                                      \
    "    vec3 c = albedo * diffuse + specular * color;\n"                             \
    "    float gloss = min(dot(specular, vec3(0.3333)), 1.0);\n"                       \
    "    return vec4(sqrt(clamp(c, 0.0, 1.0)), max(t.a, gloss));\n"                   \
    "}\n"

// Per-pixel lighting: the vertex stage passes position, normal, material on.
const char* vertex_shader = "#version 330 core\n" AVSI_ATTRIBUTES
                            "out vec3 v_position;\n"
                            "out vec3 v_normal;\n"
                            "out vec3 v_color;\n"
                            "out vec3 v_material;\n"
                            "out vec2 v_uv;\n"
                            "void main() {\n"
                            "    v_position = a_position;\n"
                            "    v_normal = a_normal;\n"
                            "    v_color = a_color;\n"
                            "    v_material = a_material;\n"
                            "    v_uv = a_uv;\n"
                            "    gl_Position = u_view_proj * vec4(a_position, 1.0);\n"
                            "}\n";

const char* fragment_shader = "#version 330 core\n"
                              "in vec3 v_position;\n"
                              "in vec3 v_normal;\n"
                              "in vec3 v_color;\n"
                              "in vec3 v_material;\n"
                              "in vec2 v_uv;\n"
                              "out vec4 o_color;\n" AVSI_LIGHTING AVSI_SURFACE
                              "void main() {\n"
                              "    vec3 diffuse, specular;\n"
                              "    light(v_position, v_normal, v_material, diffuse, specular);\n"
                              "    o_color = surface(v_uv, v_color, diffuse, specular);\n"
                              "}\n";

// Per-vertex lighting (Gouraud interpolation of the diffuse and specular
// light; the texture per pixel): the lights are evaluated at the vertices
// instead of every covered pixel — on llvmpipe about 3x faster per frame at
// 640x480, and on this dense a mesh the difference is confined to the width
// of specular highlights.
const char* vertex_lit_shader = "#version 330 core\n" AVSI_ATTRIBUTES
                                "out vec3 v_diffuse;\n"
                                "out vec3 v_specular;\n"
                                "out vec3 v_color;\n"
                                "out vec2 v_uv;\n" AVSI_LIGHTING
                                "void main() {\n"
                                "    light(a_position, a_normal, a_material, v_diffuse, v_specular);\n"
                                "    v_color = a_color;\n"
                                "    v_uv = a_uv;\n"
                                "    gl_Position = u_view_proj * vec4(a_position, 1.0);\n"
                                "}\n";

const char* vertex_lit_fragment_shader = "#version 330 core\n"
                                         "in vec3 v_diffuse;\n"
                                         "in vec3 v_specular;\n"
                                         "in vec3 v_color;\n"
                                         "in vec2 v_uv;\n"
                                         "out vec4 o_color;\n" AVSI_SURFACE
                                         "void main() { o_color = surface(v_uv, v_color, v_diffuse, v_specular); }\n";

// Region mode: the mesh group of each triangle, looked up by gl_PrimitiveID
// (alpha-textured surfaces count where they are opaque enough).
const char* region_shader = R"(#version 330 core
uniform usamplerBuffer u_groups;
uniform int u_first_triangle;
uniform sampler2D u_texture;
uniform float u_alpha_cut;
in vec2 v_uv;
out vec4 o_color;
void main() {
    if (texture(u_texture, v_uv).a < u_alpha_cut) discard;
    uint g = texelFetch(u_groups, gl_PrimitiveID + u_first_triangle).r;
    o_color = vec4(float(g + 1u) / 255.0, 0.0, 0.0, 1.0);
}
)";

// How a range of triangles is drawn.
enum class Pass { Opaque, Glossy, Blend };
constexpr int pass_count = 3;
// Materials at least this shiny are lit per pixel (a highlight narrower than the triangles).
constexpr float glossy_shininess = 60.0f;

}  // namespace

struct HeadDrawer::Impl {
    detail::Gl gl;
    // A lit program and its uniforms; [0] lights per vertex, [1] per pixel, [2] regions.
    struct Program {
        GLuint program = 0;
        GLint u_view_proj = -1, u_eye = -1, u_light_dir = -1, u_light_color = -1, u_sky = -1, u_ground = -1,
              u_scatter = -1, u_texture = -1, u_alpha_cut = -1, u_groups = -1, u_first_triangle = -1;
    };
    Program programs[3];
    GLuint vao = 0, vbo_dynamic = 0, vbo_static = 0, texture = 0;
    // The index buffer: the static triangles, then those of the clusters
    // only the blink moves, then the other moving ones; each part split by
    // pass (opaque, glossy, blended back to front); and its triangle → group
    // table for region renders. The whole head is drawn in this order too,
    // so a depth tie between a static and a moving triangle (where the
    // opened jaw passes through the neck) resolves the same way with and
    // without the static-part cache.
    GLuint ebo_split = 0, group_buffer_split = 0, group_texture_split = 0;
    struct Range {
        GLsizei first = 0, count = 0;
    };
    Range ranges[3][pass_count];  // [part: static, blink-only, moving][pass]
    std::vector<std::vector<std::uint32_t>> moving_clusters;
    std::vector<bool> blink_only_clusters;
    std::size_t vertex_count = 0;
    std::vector<float> interleaved;
    glm::vec3 target{0.0f};

    GLuint compile(GLenum type, const char* source) {
        const GLuint s = gl.glCreateShader(type);
        gl.glShaderSource(s, 1, &source, nullptr);
        gl.glCompileShader(s);
        GLint ok = 0;
        gl.glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
        if (!ok) {
            char log[2048];
            gl.glGetShaderInfoLog(s, sizeof log, nullptr, log);
            throw std::runtime_error(std::string("shader compilation failed: ") + log);
        }
        return s;
    }

    Program link(const char* vs_source, const char* fs_source) {
        const GLuint vs = compile(GL_VERTEX_SHADER, vs_source);
        const GLuint fs = compile(GL_FRAGMENT_SHADER, fs_source);
        Program p;
        p.program = gl.glCreateProgram();
        gl.glAttachShader(p.program, vs);
        gl.glAttachShader(p.program, fs);
        gl.glLinkProgram(p.program);
        gl.glDeleteShader(vs);
        gl.glDeleteShader(fs);
        GLint ok = 0;
        gl.glGetProgramiv(p.program, GL_LINK_STATUS, &ok);
        if (!ok) {
            char log[2048];
            gl.glGetProgramInfoLog(p.program, sizeof log, nullptr, log);
            throw std::runtime_error(std::string("shader link failed: ") + log);
        }
        const auto at = [&](const char* name) { return gl.glGetUniformLocation(p.program, name); };
        p.u_view_proj = at("u_view_proj");
        p.u_eye = at("u_eye");
        p.u_light_dir = at("u_light_dir");
        p.u_light_color = at("u_light_color");
        p.u_sky = at("u_sky");
        p.u_ground = at("u_ground");
        p.u_scatter = at("u_scatter");
        p.u_texture = at("u_texture");
        p.u_alpha_cut = at("u_alpha_cut");
        p.u_groups = at("u_groups");
        p.u_first_triangle = at("u_first_triangle");
        return p;
    }

    // Per-vertex colour, material (from the group of its triangles) and
    // texture coordinates, 8 floats each; each triangle's pass into `pass_of`.
    std::vector<float> vertex_statics(const Head& head, bool textured, std::vector<int>& pass_of) const {
        const auto& mesh = head.mesh;
        std::vector<float> statics(vertex_count * 8, 0.0f);
        const Material plain;
        for (std::size_t i = 0; i < vertex_count; ++i) {
            float* v = &statics[8 * i];
            v[0] = mesh.colors[i].r, v[1] = mesh.colors[i].g, v[2] = mesh.colors[i].b;
            v[3] = plain.specular, v[4] = plain.shininess, v[5] = plain.wrap;
            if (textured) v[6] = mesh.uvs[i].x, v[7] = mesh.uvs[i].y;
        }
        const std::size_t triangle_count = mesh.indices.size() / 3;
        pass_of.assign(triangle_count, int(Pass::Opaque));
        for (std::size_t t = 0; t < triangle_count; ++t) {
            const Material& m = head.materials.at(static_cast<std::size_t>(mesh.triangle_group[t]));
            pass_of[t] = int(m.blend ? Pass::Blend : m.shininess >= glossy_shininess ? Pass::Glossy : Pass::Opaque);
            for (int k = 0; k < 3; ++k) {
                float* v = &statics[8 * mesh.indices[3 * t + static_cast<std::size_t>(k)]];
                v[3] = m.specular, v[4] = m.shininess, v[5] = m.wrap;
            }
        }
        return statics;
    }

    // The vertex array: the positions and normals streamed each frame, the statics once.
    void upload_vertices(const std::vector<float>& statics) {
        gl.glGenVertexArrays(1, &vao);
        gl.glBindVertexArray(vao);
        gl.glGenBuffers(1, &vbo_dynamic);
        gl.glBindBuffer(GL_ARRAY_BUFFER, vbo_dynamic);
        gl.glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertex_count * 6 * sizeof(float)), nullptr,
                        GL_STREAM_DRAW);
        gl.glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
        gl.glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                                 reinterpret_cast<const void*>(3 * sizeof(float)));
        gl.glEnableVertexAttribArray(0);
        gl.glEnableVertexAttribArray(1);
        gl.glGenBuffers(1, &vbo_static);
        gl.glBindBuffer(GL_ARRAY_BUFFER, vbo_static);
        gl.glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(statics.size() * sizeof(float)), statics.data(),
                        GL_STATIC_DRAW);
        gl.glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, 8 * sizeof(float), nullptr);
        gl.glVertexAttribPointer(3, 3, GL_FLOAT, GL_FALSE, 8 * sizeof(float),
                                 reinterpret_cast<const void*>(3 * sizeof(float)));
        gl.glVertexAttribPointer(4, 2, GL_FLOAT, GL_FALSE, 8 * sizeof(float),
                                 reinterpret_cast<const void*>(6 * sizeof(float)));
        gl.glEnableVertexAttribArray(2);
        gl.glEnableVertexAttribArray(3);
        gl.glEnableVertexAttribArray(4);
        gl.glBindVertexArray(0);
    }

    // The texture (mipmapped, trilinear), or one white texel.
    void upload_texture(const Head& head, bool textured) {
        gl.glGenTextures(1, &texture);
        gl.glBindTexture(GL_TEXTURE_2D, texture);
        const std::uint8_t white[4] = {255, 255, 255, 255};
        if (textured) {
            // GL's first row is v = 0, the image's last (OBJ texture coordinates count from the bottom).
            const auto& tex = *head.texture;
            const std::size_t row = std::size_t(tex.width) * 4;
            std::vector<std::uint8_t> flipped(tex.rgba.size());
            for (int y = 0; y < tex.height; ++y)
                std::memcpy(&flipped[std::size_t(y) * row], &tex.rgba[std::size_t(tex.height - 1 - y) * row], row);
            gl.glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, tex.width, tex.height, 0, GL_RGBA, GL_UNSIGNED_BYTE, flipped.data());
        } else
            gl.glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, 1, 1, 0, GL_RGBA, GL_UNSIGNED_BYTE, white);
        gl.glGenerateMipmap(GL_TEXTURE_2D);
        gl.glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
        gl.glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        gl.glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        gl.glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    }

    // The static / moving split. A vertex moves when a rig transform weights
    // it; its normal (area-weighted over its triangles) changes when one of its
    // triangles has a moving vertex; a triangle's pixels change when one of its
    // vertices moves or changes normal. Sets the moving clusters and which
    // the blink alone moves; returns each triangle's part (0 static, 1
    // blink-only, 2 moving).
    std::vector<int> split_moving_parts(const Head& head) {
        const auto& mesh = head.mesh;
        const std::size_t triangle_count = mesh.indices.size() / 3;
        // moves: bit 1 = moved by a speech channel, bit 2 = moved by the blink.
        std::vector<char> moves(vertex_count, 0), reshaded(vertex_count, 0), moving_triangle(triangle_count, 0);
        // The expression channels (brows, cheeks) are left out: the renderer
        // draws a frame with an expression uncached, so the cached split stays
        // the speech-only head's.
        for (const auto& t : head.transforms) {
            if (is_expression_channel(static_cast<std::size_t>(t.channel_index))) continue;
            const char bit = is_eye_channel(static_cast<std::size_t>(t.channel_index)) ? 2 : 1;
            for (std::size_t k = 0; k < t.vertices.size(); ++k)
                if (t.weights[k] != 0.0f) moves[t.vertices[k]] |= bit;
        }
        // The lip contact moves its vertices with the speech parameters.
        if (head.lip_contact)
            for (auto v : head.lip_contact->mesh.moved) moves[v] |= 1;
        for (std::size_t t = 0; t < triangle_count; ++t) {
            const std::uint32_t* v = &mesh.indices[3 * t];
            if (moves[v[0]] || moves[v[1]] || moves[v[2]]) reshaded[v[0]] = reshaded[v[1]] = reshaded[v[2]] = 1;
        }
        for (std::size_t t = 0; t < triangle_count; ++t) {
            const std::uint32_t* v = &mesh.indices[3 * t];
            moving_triangle[t] = (reshaded[v[0]] || reshaded[v[1]] || reshaded[v[2]]) ? 1 : 0;
        }
        // Clusters: connected components of the moving triangles (union-find over vertices).
        std::vector<std::uint32_t> parent(vertex_count);
        for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<std::uint32_t>(i);
        auto find = [&](std::uint32_t x) {
            while (parent[x] != x) x = parent[x] = parent[parent[x]];
            return x;
        };
        std::vector<char> in_moving(vertex_count, 0);
        for (std::size_t t = 0; t < triangle_count; ++t) {
            if (!moving_triangle[t]) continue;
            const std::uint32_t* v = &mesh.indices[3 * t];
            for (int k = 0; k < 3; ++k) in_moving[v[k]] = 1;
            parent[find(v[1])] = find(v[0]);
            parent[find(v[2])] = find(v[0]);
        }
        std::vector<int> cluster_of_root(vertex_count, -1);
        std::vector<char> cluster_moves;  // the moves bits of each cluster's vertices
        for (std::size_t i = 0; i < vertex_count; ++i) {
            if (!in_moving[i]) continue;
            const std::uint32_t root = find(static_cast<std::uint32_t>(i));
            if (cluster_of_root[root] < 0) {
                cluster_of_root[root] = static_cast<int>(moving_clusters.size());
                moving_clusters.emplace_back();
                cluster_moves.push_back(0);
            }
            const auto c = static_cast<std::size_t>(cluster_of_root[root]);
            moving_clusters[c].push_back(static_cast<std::uint32_t>(i));
            cluster_moves[c] = static_cast<char>(cluster_moves[c] | moves[i]);
        }
        // A cluster moved by the blink alone (the eyelids) is at its rest pose in
        // every frame without a blink: it can be cached with the static part.
        blink_only_clusters.resize(moving_clusters.size());
        for (std::size_t c = 0; c < moving_clusters.size(); ++c) blink_only_clusters[c] = cluster_moves[c] == 2;
        std::vector<int> part_of(triangle_count, 0);
        for (std::size_t t = 0; t < triangle_count; ++t) {
            const std::uint32_t* v = &mesh.indices[3 * t];
            part_of[t] = !moving_triangle[t] ? 0
                         : blink_only_clusters[static_cast<std::size_t>(cluster_of_root[find(v[0])])] ? 1
                                                                                                       : 2;
        }
        return part_of;
    }

    // The triangles in drawing order: blended ones back to front as the
    // frontal camera sees them (by their centroids' depth; the camera looks
    // along −z), the others in mesh order.
    static std::vector<std::size_t> drawing_order(const HeadMesh& mesh, const std::vector<int>& pass_of) {
        const std::size_t triangle_count = mesh.indices.size() / 3;
        std::vector<std::size_t> order(triangle_count);
        for (std::size_t t = 0; t < triangle_count; ++t) order[t] = t;
        std::vector<float> depth(triangle_count);
        for (std::size_t t = 0; t < triangle_count; ++t)
            depth[t] = mesh.positions[mesh.indices[3 * t]].z + mesh.positions[mesh.indices[3 * t + 1]].z +
                       mesh.positions[mesh.indices[3 * t + 2]].z;
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
            const bool blend_a = pass_of[a] == int(Pass::Blend), blend_b = pass_of[b] == int(Pass::Blend);
            return blend_a && blend_b && depth[a] < depth[b];
        });
        return order;
    }

    // The split index buffer (parts in order, passes in order within a
    // part) and its triangle → group table (read by the region mode).
    void upload_split(const HeadMesh& mesh, const std::vector<std::size_t>& order, const std::vector<int>& part_of,
                      const std::vector<int>& pass_of) {
        const std::size_t triangle_count = mesh.indices.size() / 3;
        std::vector<std::uint8_t> groups(triangle_count);
        for (std::size_t t = 0; t < groups.size(); ++t) groups[t] = static_cast<std::uint8_t>(mesh.triangle_group[t]);
        std::vector<std::uint32_t> split;
        split.reserve(mesh.indices.size());
        std::vector<std::uint8_t> split_groups;
        split_groups.reserve(triangle_count);
        for (int part = 0; part < 3; ++part)
            for (int pass = 0; pass < pass_count; ++pass) {
                auto& r = ranges[part][pass];
                r.first = static_cast<GLsizei>(split.size());
                for (const std::size_t t : order) {
                    if (part_of[t] != part || pass_of[t] != pass) continue;
                    const std::uint32_t* v = &mesh.indices[3 * t];
                    split.insert(split.end(), v, v + 3);
                    split_groups.push_back(groups[t]);
                }
                r.count = static_cast<GLsizei>(split.size()) - r.first;
            }

        gl.glBindVertexArray(vao);
        gl.glGenBuffers(1, &ebo_split);
        gl.glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ebo_split);
        gl.glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(split.size() * sizeof(std::uint32_t)),
                        split.data(), GL_STATIC_DRAW);
        gl.glBindVertexArray(0);
        gl.glGenBuffers(1, &group_buffer_split);
        gl.glBindBuffer(GL_TEXTURE_BUFFER, group_buffer_split);
        gl.glBufferData(GL_TEXTURE_BUFFER, static_cast<GLsizeiptr>(split_groups.size()), split_groups.data(),
                        GL_STATIC_DRAW);
        gl.glGenTextures(1, &group_texture_split);
        gl.glBindTexture(GL_TEXTURE_BUFFER, group_texture_split);
        gl.glTexBuffer(GL_TEXTURE_BUFFER, GL_R8UI, group_buffer_split);
    }
};

HeadDrawer::HeadDrawer(const Head& head, GlProcLoader loader) : m_impl(std::make_unique<Impl>()) {
    auto& d = *m_impl;
    d.gl.load(loader);
    const auto& mesh = head.mesh;
    d.vertex_count = mesh.positions.size();
    d.target = head.landmarks.head_center;
    const bool textured = head.texture.has_value() && mesh.uvs.size() == d.vertex_count;
    std::vector<int> pass_of;
    d.upload_vertices(d.vertex_statics(head, textured, pass_of));
    d.upload_texture(head, textured);
    d.programs[0] = d.link(vertex_lit_shader, vertex_lit_fragment_shader);
    d.programs[1] = d.link(vertex_shader, fragment_shader);
    d.programs[2] = d.link(vertex_shader, region_shader);
    d.interleaved.resize(d.vertex_count * 6);
    const std::vector<int> part_of = d.split_moving_parts(head);
    d.upload_split(mesh, Impl::drawing_order(mesh, pass_of), part_of, pass_of);
}

HeadDrawer::~HeadDrawer() {
    auto& d = *m_impl;
    auto& gl = d.gl;
    for (const auto& p : d.programs) gl.glDeleteProgram(p.program);
    GLuint textures[] = {d.group_texture_split, d.texture};
    gl.glDeleteTextures(2, textures);
    GLuint buffers[] = {d.vbo_dynamic, d.vbo_static, d.ebo_split, d.group_buffer_split};
    gl.glDeleteBuffers(4, buffers);
    gl.glDeleteVertexArrays(1, &d.vao);
}

const std::vector<std::vector<std::uint32_t>>& HeadDrawer::moving_vertex_clusters() const {
    return m_impl->moving_clusters;
}

bool HeadDrawer::cluster_moves_only_with_blink(std::size_t cluster) const {
    return m_impl->blink_only_clusters.at(cluster);
}

namespace {

// Camera: looks at the target from a distance that shows framing_mm.
struct Camera {
    glm::vec3 eye;
    glm::mat4 view_proj;
    float yaw;
};

Camera camera_for(const RenderSettings& settings, const glm::vec3& default_target, int width, int height) {
    const float fov = glm::radians(settings.field_of_view_deg);
    const float distance = 0.5f * settings.framing_mm / std::tan(0.5f * fov);
    const float yaw = settings.camera == CameraView::ThreeQuarter ? glm::radians(35.0f) : 0.0f;
    const glm::vec3 target = settings.target.value_or(default_target);
    const glm::vec3 eye = target + distance * glm::vec3(std::sin(yaw), 0.0f, std::cos(yaw));
    const glm::mat4 view = glm::lookAt(eye, target, glm::vec3(0, 1, 0));
    const glm::mat4 proj = glm::perspective(fov, float(width) / float(height), distance - 250.0f, distance + 250.0f);
    return {eye, proj * view, yaw};
}

}  // namespace

glm::mat4 HeadDrawer::view_projection(const RenderSettings& settings, int width, int height) const {
    return camera_for(settings, m_impl->target, width, height).view_proj;
}

void HeadDrawer::draw(const PosedMesh& posed, const RenderSettings& settings, int width, int height,
                      RenderMode mode, DrawPart part) {
    auto& d = *m_impl;
    auto& gl = d.gl;
    AVSI_ASSERT(posed.positions.size() == d.vertex_count && posed.normals.size() == d.vertex_count);
    for (std::size_t i = 0; i < d.vertex_count; ++i) {
        std::memcpy(&d.interleaved[6 * i], &posed.positions[i], 3 * sizeof(float));
        std::memcpy(&d.interleaved[6 * i + 3], &posed.normals[i], 3 * sizeof(float));
    }
    gl.glBindBuffer(GL_ARRAY_BUFFER, d.vbo_dynamic);
    gl.glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(d.interleaved.size() * sizeof(float)),
                       d.interleaved.data());

    const Camera camera = camera_for(settings, d.target, width, height);
    const glm::vec3 eye = camera.eye;
    const float yaw = camera.yaw;
    const glm::mat4& view_proj = camera.view_proj;

    // Lights in world space, turning with the camera: a warm key from the
    // upper left front, a cool dim fill from the right, a rim from behind
    // above; a sky/ground ambient. The wrapped diffuse light is tinted red.
    const glm::mat3 turn = glm::mat3(glm::rotate(glm::mat4(1.0f), yaw, glm::vec3(0, 1, 0)));
    const glm::vec3 dirs[3] = {turn * glm::normalize(glm::vec3(-0.55f, 0.55f, 0.65f)),
                               turn * glm::normalize(glm::vec3(0.75f, 0.1f, 0.55f)),
                               turn * glm::normalize(glm::vec3(0.3f, 0.6f, -0.8f))};
    const glm::vec3 colors[3] = {{0.95f, 0.88f, 0.80f}, {0.26f, 0.28f, 0.33f}, {0.30f, 0.30f, 0.34f}};
    const glm::vec3 sky{0.30f, 0.31f, 0.34f}, ground{0.14f, 0.12f, 0.11f}, scatter{0.9f, 0.45f, 0.32f};

    gl.glViewport(0, 0, width, height);
    gl.glEnable(GL_DEPTH_TEST);
    if (mode == RenderMode::Regions) {
        gl.glDisable(GL_MULTISAMPLE);
        gl.glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    } else {
        if (settings.samples > 1) gl.glEnable(GL_MULTISAMPLE);
        // The background is given in sRGB; the framebuffer holds sRGB values.
        gl.glClearColor(settings.background[0], settings.background[1], settings.background[2], 1.0f);
    }
    const bool over = part == DrawPart::Moving || part == DrawPart::MovingButLids;
    if (!over) gl.glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

    gl.glActiveTexture(GL_TEXTURE0);
    gl.glBindTexture(GL_TEXTURE_2D, d.texture);
    gl.glActiveTexture(GL_TEXTURE1);
    gl.glBindTexture(GL_TEXTURE_BUFFER, d.group_texture_split);
    gl.glActiveTexture(GL_TEXTURE0);
    auto use = [&](const Impl::Program& p, float alpha_cut) {
        gl.glUseProgram(p.program);
        gl.glUniformMatrix4fv(p.u_view_proj, 1, GL_FALSE, glm::value_ptr(view_proj));
        gl.glUniform3fv(p.u_eye, 1, glm::value_ptr(eye));
        gl.glUniform3fv(p.u_light_dir, 3, glm::value_ptr(dirs[0]));
        gl.glUniform3fv(p.u_light_color, 3, glm::value_ptr(colors[0]));
        gl.glUniform3fv(p.u_sky, 1, glm::value_ptr(sky));
        gl.glUniform3fv(p.u_ground, 1, glm::value_ptr(ground));
        gl.glUniform3fv(p.u_scatter, 1, glm::value_ptr(scatter));
        gl.glUniform1i(p.u_texture, 0);
        gl.glUniform1i(p.u_groups, 1);
        gl.glUniform1f(p.u_alpha_cut, alpha_cut);
    };
    // Parts in index-buffer order.
    int first_part = 0, last_part = 2;
    if (part == DrawPart::Static) last_part = 0;
    else if (part == DrawPart::StaticAndLids) last_part = 1;
    else if (part == DrawPart::Moving) first_part = 1;
    else if (part == DrawPart::MovingButLids) first_part = 2;
    gl.glBindVertexArray(d.vao);
    for (int p = first_part; p <= last_part; ++p)
        for (int pass = 0; pass < pass_count; ++pass) {
            const auto& r = d.ranges[p][pass];
            if (r.count == 0) continue;
            const bool blend = pass == int(Pass::Blend);
            if (mode == RenderMode::Regions) {
                use(d.programs[2], blend ? 0.5f : -1.0f);
                gl.glUniform1i(d.programs[2].u_first_triangle, r.first / 3);
            } else {
                const bool per_pixel = pass != int(Pass::Opaque) || settings.per_pixel_lighting;
                use(d.programs[per_pixel ? 1 : 0], blend ? 0.02f : -1.0f);
            }
            // Every opaque part is a consistently wound surface seen from its
            // outside (the oral cavity is the outside of the skin surface
            // folded in), so back faces are never visible: culling them halves
            // the rasteriser's work. Blended cards (hair, lashes) show both sides.
            if (blend) {
                gl.glDisable(GL_CULL_FACE);
                if (mode == RenderMode::Shaded) {
                    gl.glEnable(GL_BLEND);
                    gl.glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
                    gl.glDepthMask(GL_FALSE);
                }
            } else {
                gl.glEnable(GL_CULL_FACE);
            }
            gl.glDrawElements(GL_TRIANGLES, r.count, GL_UNSIGNED_INT,
                              reinterpret_cast<const void*>(std::size_t(r.first) * sizeof(std::uint32_t)));
            if (blend) {
                gl.glDisable(GL_BLEND);
                gl.glDepthMask(GL_TRUE);
            }
        }
    gl.glBindVertexArray(0);
}

}  // namespace avsi::stimuli
