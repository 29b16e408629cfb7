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

// A pixel rectangle [x0, x1) × [y0, y1), y counted bottom-up as in `rgba`.
struct PixelRect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// The same for the pixels of `rect` only (clamped to the image); the rest of
// `rgb` (already width × height × 3) is left as it is. Each output pixel
// depends only on `rgba` within fxaa_reach_px of it, so where `rgba` did not
// change the previous output is still right.
void fxaa_region_to_rgb(const std::uint8_t* rgba, int width, int height, PixelRect rect, bool enabled,
                        std::vector<float>& luma, std::vector<std::uint8_t>& rgb);

// How far (pixels) an FXAA output pixel reads its input: the ±span_max/2
// blend taps plus the bilinear footprint, and the 3 × 3 luma neighbourhood.
constexpr int fxaa_reach_px = 6;

}  // namespace avsi::stimuli::detail
