// CPU FXAA (see fxaa.h; Lottes 2009).
#include "fxaa.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace avsi::stimuli::detail {

namespace {

constexpr float reduce_min = 1.0f / 128.0f;
constexpr float reduce_mul = 1.0f / 8.0f;
constexpr float span_max = 8.0f;
constexpr float contrast_min = 1.0f / 32.0f;  // 0.0312
constexpr float contrast_rel = 1.0f / 8.0f;

struct Rgb {
    float r, g, b;
};

// Bilinear sample at pixel coordinates (pixel centres on integers), clamped to the edges.
// Inlined: called four times per edge pixel, the hottest function of the pass.
[[gnu::always_inline]] inline Rgb sample(const std::uint8_t* rgba, int w, int h, float x, float y) {
    x = std::clamp(x, 0.0f, float(w - 1));
    y = std::clamp(y, 0.0f, float(h - 1));
    const int x0 = std::min(int(x), w - 2 < 0 ? 0 : w - 2), y0 = std::min(int(y), h - 2 < 0 ? 0 : h - 2);
    const float fx = x - float(x0), fy = y - float(y0);
    const std::uint8_t* p00 = rgba + 4 * (std::size_t(y0) * std::size_t(w) + std::size_t(x0));
    const std::uint8_t* p10 = p00 + 4;
    const std::uint8_t* p01 = p00 + 4 * std::size_t(w);
    const std::uint8_t* p11 = p01 + 4;
    auto lerp2 = [&](int c) {
        const float top = float(p00[c]) + (float(p10[c]) - float(p00[c])) * fx;
        const float bottom = float(p01[c]) + (float(p11[c]) - float(p01[c])) * fx;
        return (top + (bottom - top) * fy) * (1.0f / 255.0f);
    };
    return {lerp2(0), lerp2(1), lerp2(2)};
}

float luma_of(const Rgb& c) { return 0.299f * c.r + 0.587f * c.g + 0.114f * c.b; }

std::uint8_t to_byte(float v) { return static_cast<std::uint8_t>(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f); }

}  // namespace

void fxaa_to_rgb(const std::uint8_t* rgba, int width, int height, bool enabled, std::vector<float>& luma,
                 std::vector<std::uint8_t>& rgb) {
    rgb.resize(std::size_t(width) * std::size_t(height) * 3);
    fxaa_region_to_rgb(rgba, width, height, PixelRect{0, 0, width, height}, enabled, luma, rgb);
}

void fxaa_region_to_rgb(const std::uint8_t* rgba, int width, int height, PixelRect rect, bool enabled,
                        std::vector<float>& luma, std::vector<std::uint8_t>& rgb) {
    const std::size_t w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
    rect.x0 = std::clamp(rect.x0, 0, width), rect.x1 = std::clamp(rect.x1, rect.x0, width);
    rect.y0 = std::clamp(rect.y0, 0, height), rect.y1 = std::clamp(rect.y1, rect.y0, height);
    if (rect.x0 == rect.x1 || rect.y0 == rect.y1) return;
    const std::size_t x0 = std::size_t(rect.x0), x1 = std::size_t(rect.x1);
    const std::size_t y0 = std::size_t(rect.y0), y1 = std::size_t(rect.y1);
    // Plain conversion: RGBA bottom-up → RGB top-down.
    for (std::size_t y = y0; y < y1; ++y) {
        const std::uint8_t* src = rgba + y * w * 4;
        std::uint8_t* dst = rgb.data() + (h - 1 - y) * w * 3;
        for (std::size_t x = x0; x < x1; ++x) {
            dst[3 * x] = src[4 * x];
            dst[3 * x + 1] = src[4 * x + 1];
            dst[3 * x + 2] = src[4 * x + 2];
        }
    }
    if (!enabled || width < 3 || height < 3) return;

    // Luma of the rectangle and its one-pixel surround.
    luma.resize(w * h);
    const std::size_t lx0 = x0 > 0 ? x0 - 1 : 0, lx1 = std::min(x1 + 1, w);
    const std::size_t ly0 = y0 > 0 ? y0 - 1 : 0, ly1 = std::min(y1 + 1, h);
    for (std::size_t y = ly0; y < ly1; ++y)
        for (std::size_t i = y * w + lx0; i < y * w + lx1; ++i)
            luma[i] = (0.299f * float(rgba[4 * i]) + 0.587f * float(rgba[4 * i + 1]) +
                       0.114f * float(rgba[4 * i + 2])) *
                      (1.0f / 255.0f);
    // Interior pixels (the one-pixel border is copied as is). Rows in the
    // bottom-up source order; y + 1 is the row above. First, branch-free so
    // the compiler vectorises it, which pixels are on an edge (local contrast
    // at least max(contrast_min, l_max × contrast_rel)); then only those.
    const std::size_t ex0 = std::max<std::size_t>(x0, 1), ex1 = std::min(x1, w - 1);
    std::vector<std::uint8_t> edge(ex1 > ex0 ? ex1 - ex0 : 0);
    for (std::size_t y = std::max<std::size_t>(y0, 1); y < std::min(y1, h - 1); ++y) {
        const float* row = luma.data() + y * w;
        const float* below = row - w;
        const float* above = row + w;
        std::uint8_t* dst = rgb.data() + (h - 1 - y) * w * 3;
        for (std::size_t x = ex0; x < ex1; ++x) {
            const float l_m = row[x];
            const float l_min = std::min(l_m, std::min(std::min(above[x - 1], above[x + 1]), std::min(below[x - 1], below[x + 1])));
            const float l_max = std::max(l_m, std::max(std::max(above[x - 1], above[x + 1]), std::max(below[x - 1], below[x + 1])));
            edge[x - ex0] = l_max - l_min >= std::max(contrast_min, l_max * contrast_rel);
        }
        for (std::size_t x = ex0; x < ex1; ++x) {
            if (!edge[x - ex0]) continue;
            const float l_m = row[x];
            const float l_sw = below[x - 1], l_se = below[x + 1], l_nw = above[x - 1], l_ne = above[x + 1];
            const float l_min = std::min(l_m, std::min(std::min(l_nw, l_ne), std::min(l_sw, l_se)));
            const float l_max = std::max(l_m, std::max(std::max(l_nw, l_ne), std::max(l_sw, l_se)));
            // Along the edge: perpendicular to the luma gradient (∂L/∂x, ∂L/∂y).
            float dx = (l_nw + l_ne) - (l_sw + l_se);   // ∝ ∂L/∂y
            float dy = (l_nw + l_sw) - (l_ne + l_se);   // ∝ −∂L/∂x
            const float dir_reduce = std::max((l_nw + l_ne + l_sw + l_se) * (0.25f * reduce_mul), reduce_min);
            const float rcp_dir_min = 1.0f / (std::min(std::abs(dx), std::abs(dy)) + dir_reduce);
            dx = std::clamp(dx * rcp_dir_min, -span_max, span_max);
            dy = std::clamp(dy * rcp_dir_min, -span_max, span_max);
            const float px = float(x), py = float(y);
            const Rgb a1 = sample(rgba, width, height, px + dx * (1.0f / 3.0f - 0.5f), py + dy * (1.0f / 3.0f - 0.5f));
            const Rgb a2 = sample(rgba, width, height, px + dx * (2.0f / 3.0f - 0.5f), py + dy * (2.0f / 3.0f - 0.5f));
            const Rgb b1 = sample(rgba, width, height, px - dx * 0.5f, py - dy * 0.5f);
            const Rgb b2 = sample(rgba, width, height, px + dx * 0.5f, py + dy * 0.5f);
            const Rgb a{0.5f * (a1.r + a2.r), 0.5f * (a1.g + a2.g), 0.5f * (a1.b + a2.b)};
            const Rgb b{0.5f * a.r + 0.25f * (b1.r + b2.r), 0.5f * a.g + 0.25f * (b1.g + b2.g),
                        0.5f * a.b + 0.25f * (b1.b + b2.b)};
            const float l_b = luma_of(b);
            const Rgb& c = (l_b < l_min || l_b > l_max) ? a : b;
            dst[3 * x] = to_byte(c.r);
            dst[3 * x + 1] = to_byte(c.g);
            dst[3 * x + 2] = to_byte(c.b);
        }
    }
}

}  // namespace avsi::stimuli::detail
