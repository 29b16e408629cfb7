// Line and point figures of the adaptive SRT report and `avsi simulate-srt`,
// drawn with cairo (PNG): tracks (level by presentation, reversals ringed),
// SRT means with confidence intervals, psychometric functions, and the
// simulation's bias and spread by track length. Takes plain numbers only.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace avsi::analysis::detail {

struct XySeries {
    std::string name;
    std::vector<double> x, y;
    bool line = true;                // join the points
    bool markers = true;
    std::vector<bool> filled;        // per point: filled marker (empty: all filled)
    std::vector<bool> ringed;        // per point: a ring around the marker (reversals)
    std::vector<double> low, high;   // per point: whiskers (empty: none)
    int color = 0;                   // palette index
};

struct XyPlot {
    std::string title, x_label, y_label, caption;
    std::vector<XySeries> series;
    std::vector<std::string> x_categories;  // x = 0..n-1 labelled by these (empty: numeric axis)
    bool y_from_zero = false;
};

// Writes the figure as PNG. Throws InputError when the file cannot be written.
void write_xy_plot_png(const std::filesystem::path& path, const XyPlot& plot, int width = 800, int height = 500);

}  // namespace avsi::analysis::detail
