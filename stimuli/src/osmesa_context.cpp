// OSMesa context creation: OpenGL 3.3 core profile on Mesa's llvmpipe.
#include "osmesa_context.h"

#include <GL/osmesa.h>

#include <stdexcept>

namespace avsi::stimuli::detail {

namespace {
constexpr int window_size = 16;
}

OsmesaContext::OsmesaContext() {
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           3,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           3,
                           0};
    m_context = OSMesaCreateContextAttribs(attribs, nullptr);
    if (m_context == nullptr)
        throw std::runtime_error("OSMesa: cannot create an OpenGL 3.3 core context (is libosmesa6 installed?)");
    m_buffer.resize(4 * window_size * window_size);
    make_current();
}

OsmesaContext::~OsmesaContext() { OSMesaDestroyContext(static_cast<OSMesaContext>(m_context)); }

void OsmesaContext::make_current() {
    if (!OSMesaMakeCurrent(static_cast<OSMesaContext>(m_context), m_buffer.data(), GL_UNSIGNED_BYTE, window_size,
                           window_size))
        throw std::runtime_error("OSMesa: cannot make the context current");
}

void* OsmesaContext::proc_address(const char* name) {
    return reinterpret_cast<void*>(OSMesaGetProcAddress(name));
}

}  // namespace avsi::stimuli::detail
