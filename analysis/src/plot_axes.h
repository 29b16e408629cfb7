// The parts every cairo figure of the analysis shares: a round tick step,
// the horizontal grid with its value labels, the two axis lines, and the
// title, rotated y label and caption. Used by report_plot.cpp and
// adaptive_plot.cpp so the figures look alike.
#pragma once

#include <functional>
#include <string>

#include <cairo.h>

namespace avsi::analysis::detail {

// The plot area in pixels.
struct PlotArea {
    double left = 0, top = 0, width = 0, height = 0;
};

// A "nice" tick step for a range: 1, 2 or 5 × 10^k, about `wanted` steps.
double tick_step(double range, int wanted);

// Horizontal grid lines with their labels left of the area, at every multiple
// of `step` from `from` to `to`; `y_of` maps a value to a pixel row.
void draw_y_grid(cairo_t* cr, const PlotArea& area, double from, double to, double step,
                 const std::function<double(double)>& y_of, const std::function<std::string(double)>& label);

// The left and bottom axis lines.
void draw_axes(cairo_t* cr, const PlotArea& area);

// The title above the area, the y label rotated beside it, the caption at
// `caption_y` pixels (font sizes 16, 13, 11).
void draw_titles(cairo_t* cr, const PlotArea& area, const std::string& title, const std::string& y_label,
                 const std::string& caption, double caption_y);

}  // namespace avsi::analysis::detail
