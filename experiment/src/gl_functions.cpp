// The GL entry points of the runner's and the player's windows, through
// GLFW (see gl_functions.h).
#include "gl_functions.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <fmt/format.h>

#include "avsi/core/error.h"

namespace avsi::experiment::detail {

namespace {

template <typename F>
void fetch_gl_function(F& f, const char* name) {
    f = reinterpret_cast<F>(glfwGetProcAddress(name));
    if (!f) throw InputError("display", 0, 0, "", fmt::format("the OpenGL context lacks {}", name));
}

}  // namespace

void load_gl_functions(GlFunctions& gl, bool framebuffers) {
    fetch_gl_function(gl.BindTexture, "glBindTexture");
    fetch_gl_function(gl.Clear, "glClear");
    fetch_gl_function(gl.ClearColor, "glClearColor");
    fetch_gl_function(gl.DeleteTextures, "glDeleteTextures");
    fetch_gl_function(gl.Disable, "glDisable");
    fetch_gl_function(gl.Finish, "glFinish");
    fetch_gl_function(gl.GenTextures, "glGenTextures");
    fetch_gl_function(gl.PixelStorei, "glPixelStorei");
    fetch_gl_function(gl.ReadBuffer, "glReadBuffer");
    fetch_gl_function(gl.ReadPixels, "glReadPixels");
    fetch_gl_function(gl.TexImage2D, "glTexImage2D");
    fetch_gl_function(gl.TexParameteri, "glTexParameteri");
    fetch_gl_function(gl.TexSubImage2D, "glTexSubImage2D");
    fetch_gl_function(gl.Viewport, "glViewport");
    if (!framebuffers) return;
    fetch_gl_function(gl.GenFramebuffers, "glGenFramebuffers");
    fetch_gl_function(gl.BindFramebuffer, "glBindFramebuffer");
    fetch_gl_function(gl.FramebufferTexture2D, "glFramebufferTexture2D");
    fetch_gl_function(gl.GenRenderbuffers, "glGenRenderbuffers");
    fetch_gl_function(gl.BindRenderbuffer, "glBindRenderbuffer");
    fetch_gl_function(gl.RenderbufferStorage, "glRenderbufferStorage");
    fetch_gl_function(gl.FramebufferRenderbuffer, "glFramebufferRenderbuffer");
    fetch_gl_function(gl.CheckFramebufferStatus, "glCheckFramebufferStatus");
    fetch_gl_function(gl.DeleteFramebuffers, "glDeleteFramebuffers");
    fetch_gl_function(gl.DeleteRenderbuffers, "glDeleteRenderbuffers");
}

}  // namespace avsi::experiment::detail
