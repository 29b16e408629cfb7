// The report's figure: percent correct by condition with within-subject 95 %
// CIs, drawn with cairo (PNG and SVG). The only drawing code in the module;
// it takes plain numbers and knows nothing of the statistics.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace avsi::analysis::detail {

struct PlotData {
    std::vector<std::string> conditions;
    std::vector<double> means, ci_low, ci_high;  // in the dependent variable's unit
    std::string title;
    std::string y_label = "Keywords correct (%)";
    double y_min = 0.0, y_max = 100.0;           // the axis (percent: 0–100)
    std::string caption;  // under the axis, e.g. "error bars: 95 % within-subject CI (Cousineau-Morey)"
};

// Writes the figure as PNG (width × height pixels). Throws InputError on write failure.
void write_plot_png(const std::filesystem::path& path, const PlotData& data, int width = 800, int height = 500);
// Writes the same figure as SVG.
void write_plot_svg(const std::filesystem::path& path, const PlotData& data, int width = 800, int height = 500);

}  // namespace avsi::analysis::detail
