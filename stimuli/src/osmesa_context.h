// A minimal OSMesa GL 3.3 core context (kept apart from gl_api.h because
// GL/osmesa.h pulls in the legacy GL/gl.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace avsi::stimuli::detail {

class OsmesaContext {
public:
    // Creates a core-profile 3.3 context with a small RGBA window buffer
    // (drawing goes to framebuffer objects). Throws std::runtime_error.
    OsmesaContext();
    ~OsmesaContext();
    OsmesaContext(const OsmesaContext&) = delete;
    OsmesaContext& operator=(const OsmesaContext&) = delete;

    // Makes the context current on the calling thread.
    void make_current();
    static void* proc_address(const char* name);

private:
    void* m_context = nullptr;
    std::vector<std::uint8_t> m_buffer;
};

}  // namespace avsi::stimuli::detail
