// Rendering the talking head with OpenGL 3.3 core: the head's texture and a
// lighting model for skin (key, fill and rim lights, a sky/ground ambient,
// wrapped diffuse light tinted red past the terminator, a soft Blinn-Phong
// highlight with Fresnel; per vertex by default, per pixel on request and
// for glossy materials), alpha-blended hair, brows and lashes drawn back to
// front, anti-aliasing by a post-process pass (FXAA: Lottes 2009, "FXAA",
// NVIDIA white paper) and/or multisampling, a frontal or three-quarter
// camera. HeadDrawer holds the GL drawing code and works in any
// current GL 3.3 core context (OSMesa offscreen here, a GLFW window in the
// session runner); OffscreenRenderer owns an OSMesa context (llvmpipe, no
// display) and returns images. No GL header is included here.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>

#include "avsi/stimuli/head.h"
#include "avsi/stimuli/lod.h"

namespace avsi::stimuli {

enum class CameraView { Front, ThreeQuarter };

// What a pixel shows: the shaded face, or the index + 1 of the mesh group
// (HeadMesh::group_names) of the surface in front, in the red channel (0 = background).
enum class RenderMode { Shaded, Regions };

// Which triangles HeadDrawer::draw draws. The rig moves only some vertices
// (lips, jaw, cheeks, eyelids); a triangle is "moving" when one of its
// vertices moves or has a normal that depends on a moving vertex. With a
// fixed camera and lights the other, "static", triangles look the same in
// every frame, so they can be drawn once and their colour and depth reused.
// Moving triangles of a cluster that only the blink moves (the eyelids) are
// at their rest pose in every frame without a blink, so they can be cached
// too: StaticAndLids / MovingButLids split the head that way.
enum class DrawPart {
    All,            // clear, then every triangle (in mesh order)
    Static,         // clear, then the static triangles only
    Moving,         // no clear: the moving triangles over what the framebuffer holds
    StaticAndLids,  // clear, then the static triangles and the blink-only clusters' (right when blink = 0)
    MovingButLids,  // no clear: the moving triangles but the blink-only clusters'
};

struct RenderSettings {
    int width = 640;
    int height = 480;
    CameraView camera = CameraView::Front;
    std::array<float, 3> background{0.44f, 0.46f, 0.49f};  // sRGB in [0, 1]: a neutral grey
    // Anti-aliasing. On llvmpipe 4x MSAA costs ~3x the whole frame, so the
    // default is FXAA, a post-process pass over the finished image.
    int samples = 1;                 // MSAA samples per pixel (1 = off)
    bool fxaa = true;                // FXAA post-process pass
    bool per_pixel_lighting = false; // the lights per pixel instead of per vertex
    // Draw the static part of the head (DrawPart) once per renderer and per
    // frame only the moving triangles over its cached colour and depth, read
    // back and anti-alias only the rectangles they cover. The same picture as
    // drawing everything (up to depth ties between a static and a moving
    // triangle); ~3x faster. Not used with MSAA (samples > 1) or region renders.
    bool cache_static = true;
    float field_of_view_deg = 18.0f; // vertical
    // Height of the world shown at the target's depth: the default frames
    // head and shoulders as audiovisual speech corpora do, the face (brow to
    // chin) about half the frame height.
    float framing_mm = 340.0f;
    // The point the camera looks at (mesh units); default: the head's head_center landmark.
    std::optional<glm::vec3> target;
    // Level of detail (lod.h): OffscreenRenderer draws the head simplified
    // as this asks (the automatic choice by this frame height and framing);
    // default full detail. HeadDrawer draws the head it is given.
    LodSettings lod;
};

// Parses "front" / "three-quarter"; throws InputError otherwise.
CameraView camera_view_from_name(const std::string& name);

// An 8-bit RGB image, rows top to bottom.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgb;
    const std::uint8_t* pixel(int x, int y) const {
        return rgb.data() + 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                                 static_cast<std::size_t>(x));
    }
};

// A GL function loader: OSMesaGetProcAddress, glfwGetProcAddress, …
using GlProcLoader = void* (*)(const char* name);

// Draws a posed head in the current GL 3.3 core context. Create, use and
// destroy it on the thread where that context is current.
class HeadDrawer {
public:
    HeadDrawer(const Head& head, GlProcLoader loader);
    ~HeadDrawer();
    HeadDrawer(const HeadDrawer&) = delete;
    HeadDrawer& operator=(const HeadDrawer&) = delete;

    // Draws `part` of the head into the currently bound framebuffer of size
    // width × height (clearing it first unless part is Moving).
    void draw(const PosedMesh& posed, const RenderSettings& settings, int width, int height,
              RenderMode mode = RenderMode::Shaded, DrawPart part = DrawPart::All);

    // The camera's view-projection matrix for these settings and frame size.
    glm::mat4 view_projection(const RenderSettings& settings, int width, int height) const;

    // The vertices of the moving triangles, in clusters that move together
    // (one per connected set of rig channels: the mouth and jaw, each eye's lids).
    const std::vector<std::vector<std::uint32_t>>& moving_vertex_clusters() const;
    // Whether only the blink moves that cluster (its triangles are in StaticAndLids).
    bool cluster_moves_only_with_blink(std::size_t cluster) const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

// An offscreen renderer: its own OSMesa GL 3.3 core context (llvmpipe), a
// scene framebuffer (multisampled when samples > 1) and the FXAA pass into
// the output framebuffer that is read back. Not thread-safe; use one per thread.
class OffscreenRenderer {
public:
    OffscreenRenderer(const Head& head, const RenderSettings& settings = {});
    ~OffscreenRenderer();
    OffscreenRenderer(const OffscreenRenderer&) = delete;
    OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

    // Poses the head and renders it; `out` is resized and reused.
    void render(const Pose& pose, Image& out, RenderMode mode = RenderMode::Shaded);
    Image render(const Pose& pose, RenderMode mode = RenderMode::Shaded);

    const RenderSettings& settings() const { return m_settings; }
    // The head drawn: the one given, or its simplified version (settings().lod).
    const Head& head() const { return m_head; }
    // How the head was simplified; null at full detail (the default settings).
    const LodResult* lod() const { return m_lod.get(); }
    // The GL renderer string (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
    std::string gl_renderer() const;

private:
    void render_cached(Image& out, bool lids_at_rest);

    struct Impl;
    std::unique_ptr<const LodResult> m_lod;  // before m_head, which may refer to its head
    const Head& m_head;
    RenderSettings m_settings;
    PosedMesh m_posed;
    std::unique_ptr<Impl> m_impl;
};

}  // namespace avsi::stimuli
