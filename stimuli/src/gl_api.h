// The GL 3.3 core functions the head drawer uses, loaded through a
// get-proc-address function so the same code runs in an OSMesa context and a
// GLFW window (libepoxy cannot tell an OSMesa context from a GLX/EGL one, so
// it would resolve functions from the wrong driver).
#pragma once

#include <GL/glcorearb.h>

#include "avsi/stimuli/renderer.h"

namespace avsi::stimuli::detail {

#define AVSI_GL_FUNCTIONS(X)                                                 \
    X(PFNGLGETERRORPROC, glGetError)                                         \
    X(PFNGLGETSTRINGPROC, glGetString)                                       \
    X(PFNGLVIEWPORTPROC, glViewport)                                         \
    X(PFNGLCLEARCOLORPROC, glClearColor)                                     \
    X(PFNGLCLEARPROC, glClear)                                               \
    X(PFNGLENABLEPROC, glEnable)                                             \
    X(PFNGLDISABLEPROC, glDisable)                                           \
    X(PFNGLFINISHPROC, glFinish)                                             \
    X(PFNGLPIXELSTOREIPROC, glPixelStorei)                                   \
    X(PFNGLREADPIXELSPROC, glReadPixels)                                     \
    X(PFNGLDRAWELEMENTSPROC, glDrawElements)                                 \
    X(PFNGLGENVERTEXARRAYSPROC, glGenVertexArrays)                           \
    X(PFNGLBINDVERTEXARRAYPROC, glBindVertexArray)                           \
    X(PFNGLDELETEVERTEXARRAYSPROC, glDeleteVertexArrays)                     \
    X(PFNGLGENBUFFERSPROC, glGenBuffers)                                     \
    X(PFNGLBINDBUFFERPROC, glBindBuffer)                                     \
    X(PFNGLBUFFERDATAPROC, glBufferData)                                     \
    X(PFNGLBUFFERSUBDATAPROC, glBufferSubData)                               \
    X(PFNGLDELETEBUFFERSPROC, glDeleteBuffers)                               \
    X(PFNGLVERTEXATTRIBPOINTERPROC, glVertexAttribPointer)                   \
    X(PFNGLENABLEVERTEXATTRIBARRAYPROC, glEnableVertexAttribArray)           \
    X(PFNGLCREATESHADERPROC, glCreateShader)                                 \
    X(PFNGLSHADERSOURCEPROC, glShaderSource)                                 \
    X(PFNGLCOMPILESHADERPROC, glCompileShader)                               \
    X(PFNGLGETSHADERIVPROC, glGetShaderiv)                                   \
    X(PFNGLGETSHADERINFOLOGPROC, glGetShaderInfoLog)                         \
    X(PFNGLDELETESHADERPROC, glDeleteShader)                                 \
    X(PFNGLCREATEPROGRAMPROC, glCreateProgram)                               \
    X(PFNGLATTACHSHADERPROC, glAttachShader)                                 \
    X(PFNGLLINKPROGRAMPROC, glLinkProgram)                                   \
    X(PFNGLGETPROGRAMIVPROC, glGetProgramiv)                                 \
    X(PFNGLGETPROGRAMINFOLOGPROC, glGetProgramInfoLog)                       \
    X(PFNGLUSEPROGRAMPROC, glUseProgram)                                     \
    X(PFNGLDELETEPROGRAMPROC, glDeleteProgram)                               \
    X(PFNGLGETUNIFORMLOCATIONPROC, glGetUniformLocation)                     \
    X(PFNGLUNIFORMMATRIX4FVPROC, glUniformMatrix4fv)                         \
    X(PFNGLUNIFORM3FVPROC, glUniform3fv)                                     \
    X(PFNGLUNIFORM1IPROC, glUniform1i)                                       \
    X(PFNGLGENFRAMEBUFFERSPROC, glGenFramebuffers)                           \
    X(PFNGLBINDFRAMEBUFFERPROC, glBindFramebuffer)                           \
    X(PFNGLDELETEFRAMEBUFFERSPROC, glDeleteFramebuffers)                     \
    X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, glFramebufferRenderbuffer)           \
    X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, glCheckFramebufferStatus)             \
    X(PFNGLGENRENDERBUFFERSPROC, glGenRenderbuffers)                         \
    X(PFNGLBINDRENDERBUFFERPROC, glBindRenderbuffer)                         \
    X(PFNGLDELETERENDERBUFFERSPROC, glDeleteRenderbuffers)                   \
    X(PFNGLRENDERBUFFERSTORAGEPROC, glRenderbufferStorage)                   \
    X(PFNGLRENDERBUFFERSTORAGEMULTISAMPLEPROC, glRenderbufferStorageMultisample) \
    X(PFNGLBLITFRAMEBUFFERPROC, glBlitFramebuffer)                           \
    X(PFNGLGENTEXTURESPROC, glGenTextures)                                   \
    X(PFNGLBINDTEXTUREPROC, glBindTexture)                                   \
    X(PFNGLDELETETEXTURESPROC, glDeleteTextures)                             \
    X(PFNGLACTIVETEXTUREPROC, glActiveTexture)                               \
    X(PFNGLTEXBUFFERPROC, glTexBuffer)                                       \
    X(PFNGLTEXIMAGE2DPROC, glTexImage2D)                                     \
    X(PFNGLTEXPARAMETERIPROC, glTexParameteri)                               \
    X(PFNGLGENERATEMIPMAPPROC, glGenerateMipmap)                             \
    X(PFNGLBLENDFUNCPROC, glBlendFunc)                                       \
    X(PFNGLDEPTHMASKPROC, glDepthMask)                                       \
    X(PFNGLUNIFORM1FPROC, glUniform1f)

struct Gl {
#define AVSI_GL_MEMBER(type, name) type name = nullptr;
    AVSI_GL_FUNCTIONS(AVSI_GL_MEMBER)
#undef AVSI_GL_MEMBER

    // Resolves every function; throws std::runtime_error naming a missing one.
    void load(GlProcLoader loader);
};

}  // namespace avsi::stimuli::detail
