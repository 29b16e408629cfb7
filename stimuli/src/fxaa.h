// Fast approximate anti-aliasing (FXAA) of a finished image on the CPU:
// Lottes 2009, "FXAA" (NVIDIA white paper), the reduced "FXAA 1" kernel —
// the luma of the four diagonal neighbours gives the direction along an
// edge; two bilinear taps along it (A) and two more at ±½ (B) blend across
// the staircase; B is used unless its luma leaves the local luma range;
// pixels whose local contrast is below max(1/32, max_luma/8) are copied.
// Done on the CPU because llvmpipe's filtered texture fetches make the same
// pass as a shader cost ~2x the whole scene; here the early exit really
// skips the work for the ~95% of pixels that are not on an edge.
#pragma once

#include <cstdint>
#include <vector>

namespace avsi::stimuli::detail {

// `rgba`: width × height RGBA8 pixels, rows bottom-up (as glReadPixels gives
// them). Writes `rgb` (RGB8, rows top-down, resized) anti-aliased when
// `enabled`, else just converted. `luma` is scratch space, reused between calls.
void fxaa_to_rgb(const std::uint8_t* rgba, int width, int height, bool enabled, std::vector<float>& luma,
                 std::vector<std::uint8_t>& rgb);

}  // namespace avsi::stimuli::detail
