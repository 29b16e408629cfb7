// The GL drawing of the head: one vertex buffer (positions and normals
// updated per frame, colours and materials static), Blinn-Phong shading
// (Blinn 1977) with three directional lights — key, fill and rim — evaluated
// per vertex (default, fast on llvmpipe) or per pixel, and a region mode that writes the mesh group of each
// triangle (gl_PrimitiveID into a texture buffer) for tests.
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

// Per-pixel lighting: the vertex stage passes position, normal and material
// on, the fragment stage evaluates the lights.
const char* vertex_shader = R"(#version 330 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec3 a_color;
layout(location = 3) in vec3 a_material;
uniform mat4 u_view_proj;
out vec3 v_position;
out vec3 v_normal;
out vec3 v_color;
out vec3 v_material;
void main() {
    v_position = a_position;
    v_normal = a_normal;
    v_color = a_color;
    v_material = a_material;
    gl_Position = u_view_proj * vec4(a_position, 1.0);
}
)";

// Blinn-Phong: c = ka·albedo + Σ_lights L·(albedo·max(n·l, 0) + ks·max(n·h, 0)^shininess),
// then the sRGB-like display gamma 1/2.2. Shared by both shading rates.
#define AVSI_BLINN_PHONG                                                              \
    "uniform vec3 u_eye;\n"                                                           \
    "uniform vec3 u_light_dir[3];\n"                                                  \
    "uniform vec3 u_light_color[3];\n"                                                \
    "uniform vec3 u_ambient;\n"                                                       \
    "vec3 shade(vec3 p, vec3 n_in, vec3 albedo, vec3 material) {\n"                   \
    "    vec3 n = normalize(n_in);\n"                                                 \
    "    vec3 v = normalize(u_eye - p);\n"                                            \
    "    vec3 c = u_ambient * albedo * material.z;\n"                                 \
    "    for (int i = 0; i < 3; ++i) {\n"                                             \
    "        vec3 l = u_light_dir[i];\n"                                              \
    "        float diffuse = max(dot(n, l), 0.0);\n"                                  \
    "        vec3 h = normalize(l + v);\n"                                            \
    "        float specular = diffuse > 0.0 ? material.x * pow(max(dot(n, h), 0.0), material.y) : 0.0;\n" \
    "        c += u_light_color[i] * (albedo * diffuse + vec3(specular)) * material.z;\n" \
    "    }\n"                                                                         \
    "    return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2));\n"                          \
    "}\n"

const char* fragment_shader = "#version 330 core\n"
                              "in vec3 v_position;\n"
                              "in vec3 v_normal;\n"
                              "in vec3 v_color;\n"
                              "in vec3 v_material;   // specular strength, shininess, ambient occlusion\n"
                              "out vec4 o_color;\n" AVSI_BLINN_PHONG
                              "void main() { o_color = vec4(shade(v_position, v_normal, v_color, v_material), 1.0); }\n";

// Per-vertex lighting (Gouraud interpolation of the Blinn-Phong colour): the
// lights are evaluated at the ~17k vertices instead of every covered pixel,
// and one varying instead of four is interpolated — on llvmpipe this is
// about 3x faster per frame than per-pixel lighting at 640x480, and on this
// dense a mesh the difference is confined to the width of specular highlights.
const char* vertex_lit_shader = "#version 330 core\n"
                                "layout(location = 0) in vec3 a_position;\n"
                                "layout(location = 1) in vec3 a_normal;\n"
                                "layout(location = 2) in vec3 a_color;\n"
                                "layout(location = 3) in vec3 a_material;\n"
                                "uniform mat4 u_view_proj;\n"
                                "out vec3 v_shaded;\n" AVSI_BLINN_PHONG
                                "void main() {\n"
                                "    v_shaded = shade(a_position, a_normal, a_color, a_material);\n"
                                "    gl_Position = u_view_proj * vec4(a_position, 1.0);\n"
                                "}\n";

const char* vertex_lit_fragment_shader = R"(#version 330 core
in vec3 v_shaded;
out vec4 o_color;
void main() { o_color = vec4(v_shaded, 1.0); }
)";

// Region mode: the mesh group of each triangle, looked up by gl_PrimitiveID.
const char* region_shader = R"(#version 330 core
uniform usamplerBuffer u_groups;
uniform int u_first_triangle;
out vec4 o_color;
void main() {
    uint g = texelFetch(u_groups, gl_PrimitiveID + u_first_triangle).r;
    o_color = vec4(float(g + 1u) / 255.0, 0.0, 0.0, 1.0);
}
)";

}  // namespace

struct HeadDrawer::Impl {
    detail::Gl gl;
    // A lit program and its uniforms; [0] lights per vertex, [1] per pixel.
    struct Lit {
        GLuint program = 0;
        GLint u_view_proj = -1, u_eye = -1, u_light_dir = -1, u_light_color = -1, u_ambient = -1;
    };
    Lit lit[2];
    GLuint vao = 0, vbo_dynamic = 0, vbo_static = 0, region_program = 0;
    // The index buffer: the static triangles, then the moving ones (each part
    // in mesh order), and its triangle → group table for region renders. The
    // whole head is drawn in this order too, so a depth tie between a static
    // and a moving triangle (where the opened jaw passes through the neck)
    // resolves the same way with and without the static-part cache.
    GLuint ebo_split = 0, group_buffer_split = 0, group_texture_split = 0;
    GLsizei static_index_count = 0;
    GLsizei blink_index_count = 0;  // the blink-only clusters' triangles, after the static ones
    std::vector<std::vector<std::uint32_t>> moving_clusters;
    std::vector<bool> blink_only_clusters;
    GLsizei index_count = 0;
    std::size_t vertex_count = 0;
    std::vector<float> interleaved;
    GLint u_region_view_proj = -1, u_groups = -1, u_first_triangle = -1;
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

    GLuint link(const char* vs_source, const char* fs_source) {
        const GLuint vs = compile(GL_VERTEX_SHADER, vs_source);
        const GLuint fs = compile(GL_FRAGMENT_SHADER, fs_source);
        const GLuint program = gl.glCreateProgram();
        gl.glAttachShader(program, vs);
        gl.glAttachShader(program, fs);
        gl.glLinkProgram(program);
        gl.glDeleteShader(vs);
        gl.glDeleteShader(fs);
        GLint ok = 0;
        gl.glGetProgramiv(program, GL_LINK_STATUS, &ok);
        if (!ok) {
            char log[2048];
            gl.glGetProgramInfoLog(program, sizeof log, nullptr, log);
            throw std::runtime_error(std::string("shader link failed: ") + log);
        }
        return program;
    }
};

HeadDrawer::HeadDrawer(const Head& head, GlProcLoader loader) : m_impl(std::make_unique<Impl>()) {
    auto& d = *m_impl;
    auto& gl = d.gl;
    gl.load(loader);
    const auto& mesh = head.mesh;
    d.vertex_count = mesh.positions.size();
    d.index_count = static_cast<GLsizei>(mesh.indices.size());
    d.target = head.landmarks.head_center;

    // Per-vertex material from the group of its triangles: specular strength,
    // shininess, ambient occlusion (darkens the oral cavity).
    std::vector<float> statics(d.vertex_count * 6, 0.0f);
    for (std::size_t i = 0; i < d.vertex_count; ++i) {
        statics[6 * i + 0] = mesh.colors[i].r;
        statics[6 * i + 1] = mesh.colors[i].g;
        statics[6 * i + 2] = mesh.colors[i].b;
        statics[6 * i + 3] = 0.06f;
        statics[6 * i + 4] = 18.0f;
        statics[6 * i + 5] = 1.0f;
    }
    for (std::size_t t = 0; t < mesh.triangle_group.size(); ++t) {
        const std::string& g = mesh.group_names[static_cast<std::size_t>(mesh.triangle_group[t])];
        float spec = 0.06f, shin = 18.0f, occlusion = 1.0f;
        if (g == "eyes") spec = 0.6f, shin = 90.0f;
        else if (g.find("teeth") != std::string::npos) spec = 0.25f, shin = 40.0f, occlusion = 0.85f;
        else if (g.find("lip") != std::string::npos && g.find("lids") == std::string::npos) spec = 0.18f, shin = 30.0f;
        else if (g.find("inner") != std::string::npos) spec = 0.2f, shin = 30.0f, occlusion = 0.7f;
        else if (g.find("cavity") != std::string::npos) spec = 0.02f, occlusion = 0.35f;
        else if (g == "tongue") spec = 0.2f, shin = 30.0f, occlusion = 0.6f;
        for (int k = 0; k < 3; ++k) {
            const std::size_t v = mesh.indices[3 * t + static_cast<std::size_t>(k)];
            statics[6 * v + 3] = spec;
            statics[6 * v + 4] = shin;
            statics[6 * v + 5] = occlusion;
        }
    }

    gl.glGenVertexArrays(1, &d.vao);
    gl.glBindVertexArray(d.vao);
    gl.glGenBuffers(1, &d.vbo_dynamic);
    gl.glBindBuffer(GL_ARRAY_BUFFER, d.vbo_dynamic);
    gl.glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(d.vertex_count * 6 * sizeof(float)), nullptr,
                    GL_STREAM_DRAW);
    gl.glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
    gl.glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                             reinterpret_cast<const void*>(3 * sizeof(float)));
    gl.glEnableVertexAttribArray(0);
    gl.glEnableVertexAttribArray(1);
    gl.glGenBuffers(1, &d.vbo_static);
    gl.glBindBuffer(GL_ARRAY_BUFFER, d.vbo_static);
    gl.glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(statics.size() * sizeof(float)), statics.data(),
                    GL_STATIC_DRAW);
    gl.glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
    gl.glVertexAttribPointer(3, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                             reinterpret_cast<const void*>(3 * sizeof(float)));
    gl.glEnableVertexAttribArray(2);
    gl.glEnableVertexAttribArray(3);
    gl.glBindVertexArray(0);

    // Triangle → group, read by the region mode.
    std::vector<std::uint8_t> groups(mesh.triangle_group.size());
    for (std::size_t t = 0; t < groups.size(); ++t) groups[t] = static_cast<std::uint8_t>(mesh.triangle_group[t]);

    d.lit[0].program = d.link(vertex_lit_shader, vertex_lit_fragment_shader);
    d.lit[1].program = d.link(vertex_shader, fragment_shader);
    for (auto& lit : d.lit) {
        lit.u_view_proj = gl.glGetUniformLocation(lit.program, "u_view_proj");
        lit.u_eye = gl.glGetUniformLocation(lit.program, "u_eye");
        lit.u_light_dir = gl.glGetUniformLocation(lit.program, "u_light_dir");
        lit.u_light_color = gl.glGetUniformLocation(lit.program, "u_light_color");
        lit.u_ambient = gl.glGetUniformLocation(lit.program, "u_ambient");
    }
    d.region_program = d.link(vertex_shader, region_shader);
    d.u_region_view_proj = gl.glGetUniformLocation(d.region_program, "u_view_proj");
    d.u_groups = gl.glGetUniformLocation(d.region_program, "u_groups");
    d.u_first_triangle = gl.glGetUniformLocation(d.region_program, "u_first_triangle");
    d.interleaved.resize(d.vertex_count * 6);

    // The static / moving split. A vertex moves when a rig transform weights
    // it; its normal (area-weighted over its triangles) changes when one of its
    // triangles has a moving vertex; a triangle's pixels change when one of its
    // vertices moves or changes normal.
    const std::size_t triangle_count = mesh.indices.size() / 3;
    // moves: bit 1 = moved by a speech parameter, bit 2 = moved by the blink.
    std::vector<char> moves(d.vertex_count, 0), reshaded(d.vertex_count, 0), moving_triangle(triangle_count, 0);
    for (const auto& t : head.transforms) {
        const char bit = static_cast<std::size_t>(t.channel_index) < synth::param_count ? 1 : 2;
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
    std::vector<std::uint32_t> parent(d.vertex_count);
    for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<std::uint32_t>(i);
    auto find = [&](std::uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    std::vector<char> in_moving(d.vertex_count, 0);
    for (std::size_t t = 0; t < triangle_count; ++t) {
        if (!moving_triangle[t]) continue;
        const std::uint32_t* v = &mesh.indices[3 * t];
        for (int k = 0; k < 3; ++k) in_moving[v[k]] = 1;
        parent[find(v[1])] = find(v[0]);
        parent[find(v[2])] = find(v[0]);
    }
    std::vector<int> cluster_of_root(d.vertex_count, -1);
    std::vector<char> cluster_moves;  // the moves bits of each cluster's vertices
    for (std::size_t i = 0; i < d.vertex_count; ++i) {
        if (!in_moving[i]) continue;
        const std::uint32_t root = find(static_cast<std::uint32_t>(i));
        if (cluster_of_root[root] < 0) {
            cluster_of_root[root] = static_cast<int>(d.moving_clusters.size());
            d.moving_clusters.emplace_back();
            cluster_moves.push_back(0);
        }
        const auto c = static_cast<std::size_t>(cluster_of_root[root]);
        d.moving_clusters[c].push_back(static_cast<std::uint32_t>(i));
        cluster_moves[c] = static_cast<char>(cluster_moves[c] | moves[i]);
    }
    // A cluster moved by the blink alone (the eyelids) is at its rest pose in
    // every frame without a blink: it can be cached with the static part.
    d.blink_only_clusters.resize(d.moving_clusters.size());
    for (std::size_t c = 0; c < d.moving_clusters.size(); ++c) d.blink_only_clusters[c] = cluster_moves[c] == 2;
    // The split index buffer: static triangles, the blink-only clusters' ones,
    // the other moving ones (each part in mesh order).
    std::vector<std::uint32_t> split;
    split.reserve(mesh.indices.size());
    std::vector<std::uint8_t> split_groups;
    split_groups.reserve(triangle_count);
    for (int part = 0; part < 3; ++part)
        for (std::size_t t = 0; t < triangle_count; ++t) {
            const std::uint32_t* v = &mesh.indices[3 * t];
            const int p = !moving_triangle[t]
                              ? 0
                              : d.blink_only_clusters[static_cast<std::size_t>(cluster_of_root[find(v[0])])] ? 1 : 2;
            if (p != part) continue;
            split.insert(split.end(), v, v + 3);
            split_groups.push_back(groups[t]);
            if (p == 0) d.static_index_count += 3;
            if (p == 1) d.blink_index_count += 3;
        }

    gl.glBindVertexArray(d.vao);
    gl.glGenBuffers(1, &d.ebo_split);
    gl.glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, d.ebo_split);
    gl.glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(split.size() * sizeof(std::uint32_t)),
                    split.data(), GL_STATIC_DRAW);
    gl.glBindVertexArray(0);
    gl.glGenBuffers(1, &d.group_buffer_split);
    gl.glBindBuffer(GL_TEXTURE_BUFFER, d.group_buffer_split);
    gl.glBufferData(GL_TEXTURE_BUFFER, static_cast<GLsizeiptr>(split_groups.size()), split_groups.data(),
                    GL_STATIC_DRAW);
    gl.glGenTextures(1, &d.group_texture_split);
    gl.glBindTexture(GL_TEXTURE_BUFFER, d.group_texture_split);
    gl.glTexBuffer(GL_TEXTURE_BUFFER, GL_R8UI, d.group_buffer_split);
}

HeadDrawer::~HeadDrawer() {
    auto& d = *m_impl;
    auto& gl = d.gl;
    for (const auto& lit : d.lit) gl.glDeleteProgram(lit.program);
    gl.glDeleteProgram(d.region_program);
    gl.glDeleteTextures(1, &d.group_texture_split);
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

    // Lights in world space, turning with the camera: key from upper left
    // front (warm), fill from the right (cool, dim), rim from behind above.
    const glm::mat3 turn = glm::mat3(glm::rotate(glm::mat4(1.0f), yaw, glm::vec3(0, 1, 0)));
    const glm::vec3 dirs[3] = {turn * glm::normalize(glm::vec3(-0.6f, 0.5f, 0.65f)),
                               turn * glm::normalize(glm::vec3(0.7f, 0.05f, 0.6f)),
                               turn * glm::normalize(glm::vec3(0.3f, 0.6f, -0.8f))};
    const glm::vec3 colors[3] = {{0.98f, 0.91f, 0.82f}, {0.20f, 0.22f, 0.27f}, {0.45f, 0.45f, 0.50f}};
    const glm::vec3 ambient{0.16f, 0.16f, 0.18f};

    gl.glViewport(0, 0, width, height);
    gl.glEnable(GL_DEPTH_TEST);
    // Every part is a consistently wound surface seen from its outside (the
    // oral cavity is the outside of the skin surface folded in), so back
    // faces are never visible: culling them halves the rasteriser's work.
    gl.glEnable(GL_CULL_FACE);
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
    if (mode == RenderMode::Regions) {
        gl.glUseProgram(d.region_program);
        gl.glUniformMatrix4fv(d.u_region_view_proj, 1, GL_FALSE, glm::value_ptr(view_proj));
        gl.glActiveTexture(GL_TEXTURE0);
        gl.glBindTexture(GL_TEXTURE_BUFFER, d.group_texture_split);
        gl.glUniform1i(d.u_groups, 0);
        gl.glUniform1i(d.u_first_triangle, part == DrawPart::Moving          ? d.static_index_count / 3
                                            : part == DrawPart::MovingButLids ? (d.static_index_count + d.blink_index_count) / 3
                                                                              : 0);
    } else {
        const auto& lit = d.lit[settings.per_pixel_lighting ? 1 : 0];
        gl.glUseProgram(lit.program);
        gl.glUniformMatrix4fv(lit.u_view_proj, 1, GL_FALSE, glm::value_ptr(view_proj));
        gl.glUniform3fv(lit.u_eye, 1, glm::value_ptr(eye));
        gl.glUniform3fv(lit.u_light_dir, 3, glm::value_ptr(dirs[0]));
        gl.glUniform3fv(lit.u_light_color, 3, glm::value_ptr(colors[0]));
        gl.glUniform3fv(lit.u_ambient, 1, glm::value_ptr(ambient));
    }
    gl.glBindVertexArray(d.vao);
    // The VAO's index buffer is the split one: static, blink-only, moving.
    GLsizei first = 0, count = d.index_count;
    if (part == DrawPart::Static) count = d.static_index_count;
    else if (part == DrawPart::StaticAndLids) count = d.static_index_count + d.blink_index_count;
    else if (part == DrawPart::Moving) first = d.static_index_count;
    else if (part == DrawPart::MovingButLids) first = d.static_index_count + d.blink_index_count;
    if (part == DrawPart::Moving || part == DrawPart::MovingButLids) count = d.index_count - first;
    if (count > 0)
        gl.glDrawElements(GL_TRIANGLES, count, GL_UNSIGNED_INT,
                          reinterpret_cast<const void*>(std::size_t(first) * sizeof(std::uint32_t)));
    gl.glBindVertexArray(0);
}

}  // namespace avsi::stimuli
