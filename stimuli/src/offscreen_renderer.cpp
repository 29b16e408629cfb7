// The offscreen renderer: an OSMesa context; the head is drawn into a scene
// framebuffer (colour and depth renderbuffers, or multisample buffers
// resolved into it with glBlitFramebuffer when samples > 1), read back, and
// anti-aliased by FXAA on the CPU (fxaa.h) while it is turned into an RGB
// image, top row first.
//
// The static-part cache (RenderSettings::cache_static): the head's static
// triangles are drawn once into a cache framebuffer (colour and depth), read
// back and anti-aliased once. Each frame then restores the scene framebuffer
// from the cache where the previous frame's moving triangles were drawn,
// draws the moving triangles with the depth test against the static depth,
// and reads back and anti-aliases only the screen rectangles of the moving
// vertex clusters (widened by the FXAA reach); every other pixel is the
// cached one. Depth testing makes the result the same as drawing everything,
// except where a static and a moving triangle have exactly equal depth.
// A second cache also holds the clusters only the blink moves (the eyelids)
// at rest; frames without a blink (most) start from it and draw only the
// other moving triangles. Switching between the two caches restores the
// whole frame.
#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "avsi/core/error.h"
#include "avsi/stimuli/renderer.h"
#include "gl_api.h"
#include "fxaa.h"
#include "osmesa_context.h"

namespace avsi::stimuli {

namespace {

void* load_proc(const char* name) { return detail::OsmesaContext::proc_address(name); }

// The simplified head the settings ask for; null for full detail.
std::unique_ptr<const LodResult> simplified(const Head& head, const RenderSettings& settings) {
    if (settings.lod.full_detail()) return nullptr;
    return std::make_unique<const LodResult>(
        level_of_detail(head, settings.lod, settings.height, double(settings.framing_mm)));
}

}  // namespace

struct OffscreenRenderer::Impl {
    detail::OsmesaContext context;
    detail::Gl gl;
    std::unique_ptr<HeadDrawer> drawer;
    GLuint msaa_fbo = 0, msaa_color = 0, msaa_depth = 0;  // samples > 1 only
    GLuint scene_fbo = 0, scene_color = 0, scene_depth = 0;
    std::vector<std::uint8_t> rgba;
    std::vector<float> luma;  // FXAA scratch
    std::string renderer_name;
    // The static-part caches: [0] the static part, [1] it and the eyelids at rest.
    bool cached = false;
    bool has_lids = false;  // the head has clusters only the blink moves
    GLuint cache_fbo[2] = {0, 0}, cache_color[2] = {0, 0}, cache_depth[2] = {0, 0};
    bool cache_ready[2] = {false, false};
    int scene_base = -1;  // the cache the scene holds but for previous_rects; -1: none
    std::vector<std::uint8_t> static_rgba[2];  // the cached part, read back
    std::vector<std::uint8_t> static_rgb[2];   // … and anti-aliased
    std::vector<detail::PixelRect> previous_rects;  // where the last frame's moving triangles were read back
    glm::mat4 view_proj{1.0f};

    // The screen rectangles (bottom-up rows, clamped) of the moving vertex
    // clusters (but the blink-only ones when `skip_lids`), widened by `margin`
    // pixels; overlapping rectangles are merged.
    std::vector<detail::PixelRect> moving_rects(const PosedMesh& posed, int w, int h, int margin, bool skip_lids) const;
    // Copies `r` from cache `base` into the scene framebuffer (colour and depth).
    void restore(const detail::PixelRect& r, int base);

};

OffscreenRenderer::OffscreenRenderer(const Head& head, const RenderSettings& settings)
    : m_lod(simplified(head, settings)),
      m_head(m_lod ? m_lod->head : head),
      m_settings(settings),
      m_impl(std::make_unique<Impl>()) {
    if (settings.width < 16 || settings.height < 16 || settings.width > 8192 || settings.height > 8192)
        throw InputError(Diagnostic{"", 0, 0, "render.width/height",
                                    "expected a size in [16, 8192], got " + std::to_string(settings.width) + "x" +
                                        std::to_string(settings.height)});
    if (settings.samples < 1 || settings.samples > 16)
        throw InputError(Diagnostic{"", 0, 0, "render.samples",
                                    "expected 1 to 16 samples, got " + std::to_string(settings.samples)});
    auto& d = *m_impl;
    auto& gl = d.gl;
    gl.load(&load_proc);
    d.renderer_name = reinterpret_cast<const char*>(gl.glGetString(GL_RENDERER));
    const int w = settings.width, h = settings.height;

    if (settings.samples > 1) {
        gl.glGenFramebuffers(1, &d.msaa_fbo);
        gl.glBindFramebuffer(GL_FRAMEBUFFER, d.msaa_fbo);
        gl.glGenRenderbuffers(1, &d.msaa_color);
        gl.glBindRenderbuffer(GL_RENDERBUFFER, d.msaa_color);
        gl.glRenderbufferStorageMultisample(GL_RENDERBUFFER, settings.samples, GL_RGBA8, w, h);
        gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, d.msaa_color);
        gl.glGenRenderbuffers(1, &d.msaa_depth);
        gl.glBindRenderbuffer(GL_RENDERBUFFER, d.msaa_depth);
        gl.glRenderbufferStorageMultisample(GL_RENDERBUFFER, settings.samples, GL_DEPTH_COMPONENT24, w, h);
        gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, d.msaa_depth);
        if (gl.glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw std::runtime_error("OpenGL: the multisample framebuffer is incomplete");
    }
    // The scene: colour and depth.
    gl.glGenFramebuffers(1, &d.scene_fbo);
    gl.glBindFramebuffer(GL_FRAMEBUFFER, d.scene_fbo);
    gl.glGenRenderbuffers(1, &d.scene_color);
    gl.glBindRenderbuffer(GL_RENDERBUFFER, d.scene_color);
    gl.glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
    gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, d.scene_color);
    gl.glGenRenderbuffers(1, &d.scene_depth);
    gl.glBindRenderbuffer(GL_RENDERBUFFER, d.scene_depth);
    gl.glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
    gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, d.scene_depth);
    if (gl.glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw std::runtime_error("OpenGL: the scene framebuffer is incomplete");

    d.drawer = std::make_unique<HeadDrawer>(m_head, &load_proc);
    d.rgba.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);

    if (settings.cache_static && settings.samples == 1) {
        d.cached = true;
        for (std::size_t c = 0; c < d.drawer->moving_vertex_clusters().size(); ++c)
            d.has_lids = d.has_lids || d.drawer->cluster_moves_only_with_blink(c);
        for (int b = 0; b < (d.has_lids ? 2 : 1); ++b) {
            gl.glGenFramebuffers(1, &d.cache_fbo[b]);
            gl.glBindFramebuffer(GL_FRAMEBUFFER, d.cache_fbo[b]);
            gl.glGenRenderbuffers(1, &d.cache_color[b]);
            gl.glBindRenderbuffer(GL_RENDERBUFFER, d.cache_color[b]);
            gl.glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
            gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, d.cache_color[b]);
            gl.glGenRenderbuffers(1, &d.cache_depth[b]);
            gl.glBindRenderbuffer(GL_RENDERBUFFER, d.cache_depth[b]);
            gl.glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
            gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, d.cache_depth[b]);
            if (gl.glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
                throw std::runtime_error("OpenGL: the cache framebuffer is incomplete");
        }
        d.view_proj = d.drawer->view_projection(settings, w, h);
    }
}

std::vector<detail::PixelRect> OffscreenRenderer::Impl::moving_rects(const PosedMesh& posed, int w, int h,
                                                                     int margin, bool skip_lids) const {
    std::vector<detail::PixelRect> rects;
    const auto& clusters = drawer->moving_vertex_clusters();
    for (std::size_t c = 0; c < clusters.size(); ++c) {
        if (skip_lids && drawer->cluster_moves_only_with_blink(c)) continue;
        const auto& cluster = clusters[c];
        float x_min = 1e30f, y_min = 1e30f, x_max = -1e30f, y_max = -1e30f;
        bool behind = false;
        for (const std::uint32_t v : cluster) {
            const glm::vec4 c = view_proj * glm::vec4(posed.positions[v], 1.0f);
            if (!(c.w > 1e-3f)) {
                behind = true;
                break;
            }
            const float x = (c.x / c.w * 0.5f + 0.5f) * float(w), y = (c.y / c.w * 0.5f + 0.5f) * float(h);
            x_min = std::min(x_min, x), x_max = std::max(x_max, x);
            y_min = std::min(y_min, y), y_max = std::max(y_max, y);
        }
        detail::PixelRect r{0, 0, w, h};
        if (!behind) {
            // Pixel centres covered by a triangle lie inside its vertices' bounding box.
            const auto lo = [&](float v, int size) { return int(std::clamp(std::floor(v), -1.0f, float(size))) - margin; };
            const auto hi = [&](float v, int size) { return int(std::clamp(std::ceil(v), -1.0f, float(size))) + 1 + margin; };
            r = {std::max(lo(x_min, w), 0), std::max(lo(y_min, h), 0), std::min(hi(x_max, w), w),
                 std::min(hi(y_max, h), h)};
            if (r.x0 >= r.x1 || r.y0 >= r.y1) continue;  // off screen
        }
        rects.push_back(r);
    }
    // Merge overlapping rectangles until none overlap.
    for (bool merged = true; merged;) {
        merged = false;
        for (std::size_t i = 0; i < rects.size() && !merged; ++i)
            for (std::size_t j = i + 1; j < rects.size() && !merged; ++j) {
                auto& a = rects[i];
                const auto& b = rects[j];
                if (a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1) {
                    a = {std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1), std::max(a.y1, b.y1)};
                    rects.erase(rects.begin() + std::ptrdiff_t(j));
                    merged = true;
                }
            }
    }
    return rects;
}

void OffscreenRenderer::Impl::restore(const detail::PixelRect& r, int base) {
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, cache_fbo[base]);
    gl.glBindFramebuffer(GL_DRAW_FRAMEBUFFER, scene_fbo);
    gl.glBlitFramebuffer(r.x0, r.y0, r.x1, r.y1, r.x0, r.y0, r.x1, r.y1, GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT,
                         GL_NEAREST);
}

OffscreenRenderer::~OffscreenRenderer() {
    auto& d = *m_impl;
    d.context.make_current();
    d.drawer.reset();
    auto& gl = d.gl;
    GLuint fbos[] = {d.msaa_fbo, d.scene_fbo, d.cache_fbo[0], d.cache_fbo[1]};
    gl.glDeleteFramebuffers(4, fbos);
    GLuint rbs[] = {d.msaa_color,     d.msaa_depth,     d.scene_color,    d.scene_depth,
                    d.cache_color[0], d.cache_depth[0], d.cache_color[1], d.cache_depth[1]};
    gl.glDeleteRenderbuffers(8, rbs);
}

std::string OffscreenRenderer::gl_renderer() const { return m_impl->renderer_name; }

void OffscreenRenderer::render(const Pose& pose, Image& out, RenderMode mode) {
    auto& d = *m_impl;
    auto& gl = d.gl;
    const int w = m_settings.width, h = m_settings.height;
    d.context.make_current();
    pose_head(m_head, pose, m_posed);
    // The head's rotation is a rigid model transform after the rig; with it
    // (or an expression) every triangle may change, so the static caches
    // do not apply to the frame (they stay valid for the frames at rest).
    apply_head_rotation(m_head, pose.head_rotation, m_posed);
    if (d.cached && mode == RenderMode::Shaded && pose.head_at_rest() && pose.expression_at_rest()) {
        render_cached(out, d.has_lids && pose.eyes_at_rest());  // pose_head leaves a zero channel at rest
        return;
    }
    d.scene_base = -1;
    // Regions are exact group indices: never multisampled or filtered.
    const bool msaa = d.msaa_fbo != 0 && mode == RenderMode::Shaded;
    gl.glBindFramebuffer(GL_FRAMEBUFFER, msaa ? d.msaa_fbo : d.scene_fbo);
    d.drawer->draw(m_posed, m_settings, w, h, mode);
    if (msaa) {
        gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, d.msaa_fbo);
        gl.glBindFramebuffer(GL_DRAW_FRAMEBUFFER, d.scene_fbo);
        gl.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, d.scene_fbo);
    gl.glPixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, d.rgba.data());
    const GLenum error = gl.glGetError();
    if (error != GL_NO_ERROR) throw std::runtime_error("OpenGL error " + std::to_string(error) + " while rendering");
    out.width = w;
    out.height = h;
    // Regions are exact group indices: never filtered.
    detail::fxaa_to_rgb(d.rgba.data(), w, h, m_settings.fxaa && mode == RenderMode::Shaded, d.luma, out.rgb);
}

void OffscreenRenderer::render_cached(Image& out, bool lids_at_rest) {
    auto& d = *m_impl;
    auto& gl = d.gl;
    const int w = m_settings.width, h = m_settings.height;
    const bool fxaa = m_settings.fxaa;
    const int base = lids_at_rest ? 1 : 0;
    gl.glPixelStorei(GL_PACK_ALIGNMENT, 1);
    if (!d.cache_ready[base]) {
        // The cached part, once: drawn, read back, anti-aliased.
        gl.glBindFramebuffer(GL_FRAMEBUFFER, d.cache_fbo[base]);
        d.drawer->draw(m_posed, m_settings, w, h, RenderMode::Shaded,
                       lids_at_rest ? DrawPart::StaticAndLids : DrawPart::Static);
        gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, d.cache_fbo[base]);
        d.static_rgba[base].resize(d.rgba.size());
        gl.glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, d.static_rgba[base].data());
        detail::fxaa_to_rgb(d.static_rgba[base].data(), w, h, fxaa, d.luma, d.static_rgb[base]);
        d.cache_ready[base] = true;
    }
    if (d.scene_base != base) {
        // The first frame, one after an uncached render (regions) used the
        // scene, or a switch between the caches (a blink starts or ends).
        d.restore({0, 0, w, h}, base);
        d.rgba = d.static_rgba[base];
        d.previous_rects.clear();
        d.scene_base = base;
    } else {
        // Undo the previous frame's moving triangles.
        for (const auto& r : d.previous_rects) {
            d.restore(r, base);
            for (int y = r.y0; y < r.y1; ++y) {
                const std::size_t at = 4 * (std::size_t(y) * std::size_t(w) + std::size_t(r.x0));
                std::memcpy(d.rgba.data() + at, d.static_rgba[base].data() + at, 4 * std::size_t(r.x1 - r.x0));
            }
        }
    }
    gl.glBindFramebuffer(GL_FRAMEBUFFER, d.scene_fbo);
    d.drawer->draw(m_posed, m_settings, w, h, RenderMode::Shaded,
                   lids_at_rest ? DrawPart::MovingButLids : DrawPart::Moving);
    d.previous_rects = d.moving_rects(m_posed, w, h, 1, lids_at_rest);
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, d.scene_fbo);
    gl.glPixelStorei(GL_PACK_ROW_LENGTH, w);
    for (const auto& r : d.previous_rects) {
        const std::size_t at = 4 * (std::size_t(r.y0) * std::size_t(w) + std::size_t(r.x0));
        gl.glReadPixels(r.x0, r.y0, r.x1 - r.x0, r.y1 - r.y0, GL_RGBA, GL_UNSIGNED_BYTE, d.rgba.data() + at);
    }
    gl.glPixelStorei(GL_PACK_ROW_LENGTH, 0);
    const GLenum error = gl.glGetError();
    if (error != GL_NO_ERROR) throw std::runtime_error("OpenGL error " + std::to_string(error) + " while rendering");
    out.width = w;
    out.height = h;
    out.rgb = d.static_rgb[base];
    for (const auto& r : d.previous_rects) {
        const int reach = fxaa ? detail::fxaa_reach_px : 0;
        detail::fxaa_region_to_rgb(d.rgba.data(), w, h, {r.x0 - reach, r.y0 - reach, r.x1 + reach, r.y1 + reach},
                                   fxaa, d.luma, out.rgb);
    }
}

Image OffscreenRenderer::render(const Pose& pose, RenderMode mode) {
    Image image;
    render(pose, image, mode);
    return image;
}

}  // namespace avsi::stimuli
