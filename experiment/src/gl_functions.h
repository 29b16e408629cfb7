// The OpenGL entry points the session runner (runner.cpp) and the player
// (player.cpp) call themselves, fetched through GLFW from the window's
// context: the avsi helpers also link OSMesa (the offscreen renderer), whose
// exported gl* symbols must not be called on a GLFW window.
#pragma once

#include <GL/gl.h>

#ifndef GL_FRAMEBUFFER
#define GL_FRAMEBUFFER 0x8D40
#define GL_RENDERBUFFER 0x8D41
#define GL_COLOR_ATTACHMENT0 0x8CE0
#define GL_DEPTH_ATTACHMENT 0x8D00
#define GL_DEPTH_COMPONENT24 0x81A6
#define GL_FRAMEBUFFER_COMPLETE 0x8CD5
#endif

namespace avsi::experiment::detail {

struct GlFunctions {
    // OpenGL 1.1.
    void (*BindTexture)(GLenum, GLuint) = nullptr;
    void (*Clear)(GLbitfield) = nullptr;
    void (*ClearColor)(GLfloat, GLfloat, GLfloat, GLfloat) = nullptr;
    void (*DeleteTextures)(GLsizei, const GLuint*) = nullptr;
    void (*Disable)(GLenum) = nullptr;
    void (*Finish)(void) = nullptr;
    void (*GenTextures)(GLsizei, GLuint*) = nullptr;
    void (*PixelStorei)(GLenum, GLint) = nullptr;
    void (*ReadBuffer)(GLenum) = nullptr;
    void (*ReadPixels)(GLint, GLint, GLsizei, GLsizei, GLenum, GLenum, void*) = nullptr;
    void (*TexImage2D)(GLenum, GLint, GLint, GLsizei, GLsizei, GLint, GLenum, GLenum, const void*) = nullptr;
    void (*TexParameteri)(GLenum, GLenum, GLint) = nullptr;
    void (*TexSubImage2D)(GLenum, GLint, GLint, GLint, GLsizei, GLsizei, GLenum, GLenum, const void*) = nullptr;
    void (*Viewport)(GLint, GLint, GLsizei, GLsizei) = nullptr;
    // Framebuffer objects (OpenGL 3.0): only when asked for.
    void (*GenFramebuffers)(GLsizei, GLuint*) = nullptr;
    void (*BindFramebuffer)(GLenum, GLuint) = nullptr;
    void (*FramebufferTexture2D)(GLenum, GLenum, GLenum, GLuint, GLint) = nullptr;
    void (*GenRenderbuffers)(GLsizei, GLuint*) = nullptr;
    void (*BindRenderbuffer)(GLenum, GLuint) = nullptr;
    void (*RenderbufferStorage)(GLenum, GLenum, GLsizei, GLsizei) = nullptr;
    void (*FramebufferRenderbuffer)(GLenum, GLenum, GLenum, GLuint) = nullptr;
    GLenum (*CheckFramebufferStatus)(GLenum) = nullptr;
    void (*DeleteFramebuffers)(GLsizei, const GLuint*) = nullptr;
    void (*DeleteRenderbuffers)(GLsizei, const GLuint*) = nullptr;
};

// Fetches the GL 1.1 entry points, and the framebuffer-object ones when
// `framebuffers`, from the current GLFW context into `gl`; throws InputError
// naming the first one the context lacks.
void load_gl_functions(GlFunctions& gl, bool framebuffers);

}  // namespace avsi::experiment::detail
