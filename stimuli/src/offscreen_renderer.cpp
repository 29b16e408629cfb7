// The offscreen renderer: an OSMesa context; the head is drawn into a scene
// framebuffer (colour and depth renderbuffers, or multisample buffers
// resolved into it with glBlitFramebuffer when samples > 1), read back, and
// anti-aliased by FXAA on the CPU (fxaa.h) while it is turned into an RGB
// image, top row first.
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

};

OffscreenRenderer::OffscreenRenderer(const Head& head, const RenderSettings& settings)
    : m_head(head), m_settings(settings), m_impl(std::make_unique<Impl>()) {
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

    d.drawer = std::make_unique<HeadDrawer>(head, &load_proc);
    d.rgba.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
}

OffscreenRenderer::~OffscreenRenderer() {
    auto& d = *m_impl;
    d.context.make_current();
    d.drawer.reset();
    auto& gl = d.gl;
    GLuint fbos[] = {d.msaa_fbo, d.scene_fbo};
    gl.glDeleteFramebuffers(2, fbos);
    GLuint rbs[] = {d.msaa_color, d.msaa_depth, d.scene_color, d.scene_depth};
    gl.glDeleteRenderbuffers(4, rbs);
}

std::string OffscreenRenderer::gl_renderer() const { return m_impl->renderer_name; }

void OffscreenRenderer::render(const Pose& pose, Image& out, RenderMode mode) {
    auto& d = *m_impl;
    auto& gl = d.gl;
    const int w = m_settings.width, h = m_settings.height;
    d.context.make_current();
    pose_head(m_head, pose, m_posed);
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

Image OffscreenRenderer::render(const Pose& pose, RenderMode mode) {
    Image image;
    render(pose, image, mode);
    return image;
}

}  // namespace avsi::stimuli
