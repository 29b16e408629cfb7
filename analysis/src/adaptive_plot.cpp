// Cairo drawing of the adaptive SRT figures (see adaptive_plot.h).
#include "adaptive_plot.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <cairo.h>
#include <fmt/format.h>

#include "avsi/core/error.h"
#include "plot_axes.h"

namespace avsi::analysis::detail {

namespace {

struct Rgb {
    double r, g, b;
};
constexpr Rgb kPalette[] = {{0.12, 0.40, 0.70}, {0.85, 0.37, 0.01}, {0.11, 0.62, 0.47},
                            {0.46, 0.44, 0.70}, {0.91, 0.16, 0.54}, {0.40, 0.40, 0.40}};

std::string tick_label(double v, double step) {
    if (std::fabs(v) < step * 1e-9) v = 0.0;
    return step >= 1 ? fmt::format("{:.0f}", v) : (step >= 0.1 ? fmt::format("{:.1f}", v) : fmt::format("{:.2f}", v));
}

}  // namespace

void write_xy_plot_png(const std::filesystem::path& path, const XyPlot& plot, int width, int height) {
    double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
    for (const auto& s : plot.series)
        for (std::size_t i = 0; i < s.x.size(); ++i) {
            x0 = std::min(x0, s.x[i]);
            x1 = std::max(x1, s.x[i]);
            y0 = std::min(y0, s.y[i]);
            y1 = std::max(y1, s.y[i]);
            if (!s.low.empty()) y0 = std::min(y0, s.low[i]);
            if (!s.high.empty()) y1 = std::max(y1, s.high[i]);
        }
    if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
    if (!plot.x_categories.empty()) x0 = -0.5, x1 = plot.x_categories.size() - 0.5;
    if (plot.y_from_zero) y0 = std::min(0.0, y0);
    if (x1 - x0 < 1e-9) x0 -= 1, x1 += 1;
    if (y1 - y0 < 1e-9) y0 -= 1, y1 += 1;
    const double y_step = tick_step(y1 - y0, 6);
    y0 = std::floor(y0 / y_step) * y_step;
    y1 = std::ceil(y1 / y_step) * y_step;

    const double left = 80, right = plot.series.size() > 1 ? 170 : 30, top = 50, bottom = 90;
    const double pw = width - left - right, ph = height - top - bottom;
    auto X = [&](double v) { return left + pw * (v - x0) / (x1 - x0); };
    auto Y = [&](double v) { return top + ph * (1.0 - (v - y0) / (y1 - y0)); };

    cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height);
    cairo_t* cr = cairo_create(surface);
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, 12);
    const PlotArea area{left, top, pw, ph};
    draw_y_grid(cr, area, y0, y1, y_step, Y, [y_step](double v) { return tick_label(v, y_step); });
    // x ticks: categories or numbers.
    cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
    if (!plot.x_categories.empty()) {
        for (std::size_t j = 0; j < plot.x_categories.size(); ++j) {
            cairo_text_extents_t ext;
            cairo_text_extents(cr, plot.x_categories[j].c_str(), &ext);
            cairo_move_to(cr, X(double(j)) - ext.width / 2, top + ph + 18);
            cairo_show_text(cr, plot.x_categories[j].c_str());
        }
    } else {
        const double x_step = tick_step(x1 - x0, 8);
        for (double v = std::ceil(x0 / x_step) * x_step; v <= x1 + x_step * 1e-6; v += x_step) {
            const std::string label = tick_label(v, x_step);
            cairo_text_extents_t ext;
            cairo_text_extents(cr, label.c_str(), &ext);
            cairo_move_to(cr, X(v) - ext.width / 2, top + ph + 18);
            cairo_show_text(cr, label.c_str());
        }
    }
    draw_axes(cr, area);

    for (std::size_t si = 0; si < plot.series.size(); ++si) {
        const XySeries& s = plot.series[si];
        const Rgb c = kPalette[static_cast<std::size_t>(s.color) % std::size(kPalette)];
        cairo_set_source_rgb(cr, c.r, c.g, c.b);
        if (s.line && s.x.size() > 1) {
            cairo_set_line_width(cr, 1.8);
            cairo_move_to(cr, X(s.x[0]), Y(s.y[0]));
            for (std::size_t i = 1; i < s.x.size(); ++i) cairo_line_to(cr, X(s.x[i]), Y(s.y[i]));
            cairo_stroke(cr);
        }
        for (std::size_t i = 0; i < s.x.size(); ++i) {
            const double px = X(s.x[i]), py = Y(s.y[i]);
            if (!s.low.empty()) {
                cairo_set_line_width(cr, 1.5);
                cairo_move_to(cr, px, Y(s.low[i]));
                cairo_line_to(cr, px, Y(s.high[i]));
                cairo_move_to(cr, px - 7, Y(s.low[i]));
                cairo_line_to(cr, px + 7, Y(s.low[i]));
                cairo_move_to(cr, px - 7, Y(s.high[i]));
                cairo_line_to(cr, px + 7, Y(s.high[i]));
                cairo_stroke(cr);
            }
            if (s.markers) {
                cairo_new_sub_path(cr);
                cairo_arc(cr, px, py, 4.0, 0, 2 * M_PI);
                const bool fill = s.filled.empty() || s.filled[i];
                if (fill) {
                    cairo_fill(cr);
                } else {
                    cairo_set_source_rgb(cr, 1, 1, 1);
                    cairo_fill_preserve(cr);
                    cairo_set_source_rgb(cr, c.r, c.g, c.b);
                    cairo_set_line_width(cr, 1.5);
                    cairo_stroke(cr);
                }
            }
            if (!s.ringed.empty() && s.ringed[i]) {
                cairo_set_line_width(cr, 1.2);
                cairo_new_sub_path(cr);
                cairo_arc(cr, px, py, 8.0, 0, 2 * M_PI);
                cairo_stroke(cr);
            }
        }
        // Legend.
        if (plot.series.size() > 1) {
            const double ly = top + 10 + 20 * double(si);
            cairo_rectangle(cr, left + pw + 15, ly - 8, 14, 10);
            cairo_fill(cr);
            cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
            cairo_move_to(cr, left + pw + 35, ly + 2);
            cairo_show_text(cr, s.name.c_str());
        }
    }
    draw_titles(cr, area, plot.title, plot.y_label, plot.caption, height - 14);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_font_size(cr, 13);
    cairo_text_extents_t ext;
    cairo_text_extents(cr, plot.x_label.c_str(), &ext);
    cairo_move_to(cr, left + pw / 2 - ext.width / 2, top + ph + 42);
    cairo_show_text(cr, plot.x_label.c_str());
    cairo_destroy(cr);
    const cairo_status_t status = cairo_surface_write_to_png(surface, path.c_str());
    cairo_surface_destroy(surface);
    if (status != CAIRO_STATUS_SUCCESS)
        throw InputError(path, fmt::format("cannot write the plot: {}", cairo_status_to_string(status)));
}

}  // namespace avsi::analysis::detail
