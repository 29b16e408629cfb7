// The offscreen renderer: an OSMesa context, a multisample framebuffer that
// the head is drawn into, a single-sample framebuffer it is resolved into
// (glBlitFramebuffer), and a read-back into an RGB image, top row first.
#include <cstring>
#include <stdexcept>

#include "avsi/core/error.h"
#include "avsi/stimuli/renderer.h"
#include "gl_api.h"
#include "osmesa_context.h"

namespace avsi::stimuli {

struct OffscreenRenderer::Impl {
    detail::OsmesaContext context;
    detail::Gl gl;
    std::unique_ptr<HeadDrawer> drawer;
    GLuint msaa_fbo = 0, msaa_color = 0, msaa_depth = 0;
    GLuint resolve_fbo = 0, resolve_color = 0;
    std::vector<std::uint8_t> rgba;
    std::string renderer_name;
};

namespace {
void* load_proc(const char* name) { return detail::OsmesaContext::proc_address(name); }
}  // namespace

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
    gl.glGenFramebuffers(1, &d.resolve_fbo);
    gl.glBindFramebuffer(GL_FRAMEBUFFER, d.resolve_fbo);
    gl.glGenRenderbuffers(1, &d.resolve_color);
    gl.glBindRenderbuffer(GL_RENDERBUFFER, d.resolve_color);
    gl.glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
    gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, d.resolve_color);
    if (gl.glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw std::runtime_error("OpenGL: the resolve framebuffer is incomplete");
    d.drawer = std::make_unique<HeadDrawer>(head, &load_proc);
    d.rgba.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
}

OffscreenRenderer::~OffscreenRenderer() {
    auto& d = *m_impl;
    d.context.make_current();
    d.drawer.reset();
    GLuint fbos[] = {d.msaa_fbo, d.resolve_fbo};
    d.gl.glDeleteFramebuffers(2, fbos);
    GLuint rbs[] = {d.msaa_color, d.msaa_depth, d.resolve_color};
    d.gl.glDeleteRenderbuffers(3, rbs);
}

std::string OffscreenRenderer::gl_renderer() const { return m_impl->renderer_name; }

void OffscreenRenderer::render(const Pose& pose, Image& out, RenderMode mode) {
    auto& d = *m_impl;
    auto& gl = d.gl;
    const int w = m_settings.width, h = m_settings.height;
    d.context.make_current();
    pose_head(m_head, pose, m_posed);
    gl.glBindFramebuffer(GL_FRAMEBUFFER, d.msaa_fbo);
    d.drawer->draw(m_posed, m_settings, w, h, mode);
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, d.msaa_fbo);
    gl.glBindFramebuffer(GL_DRAW_FRAMEBUFFER, d.resolve_fbo);
    gl.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, d.resolve_fbo);
    gl.glPixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, d.rgba.data());
    const GLenum error = gl.glGetError();
    if (error != GL_NO_ERROR) throw std::runtime_error("OpenGL error " + std::to_string(error) + " while rendering");
    out.width = w;
    out.height = h;
    out.rgb.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
    // GL rows are bottom-up; images are top-down.
    for (int y = 0; y < h; ++y) {
        const std::uint8_t* src = d.rgba.data() + static_cast<std::size_t>(h - 1 - y) * static_cast<std::size_t>(w) * 4;
        std::uint8_t* dst = out.rgb.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w) * 3;
        for (int x = 0; x < w; ++x) {
            dst[3 * x] = src[4 * x];
            dst[3 * x + 1] = src[4 * x + 1];
            dst[3 * x + 2] = src[4 * x + 2];
        }
    }
}

Image OffscreenRenderer::render(const Pose& pose, RenderMode mode) {
    Image image;
    render(pose, image, mode);
    return image;
}

}  // namespace avsi::stimuli
