// Cairo drawing of the report figure (see report_plot.h).
#include "report_plot.h"

#include <algorithm>
#include <cmath>

#include <cairo-svg.h>
#include <cairo.h>
#include <fmt/format.h>

#include "avsi/core/error.h"
#include "plot_axes.h"

namespace avsi::analysis::detail {

namespace {

void draw(cairo_t* cr, const PlotData& d, double width, double height) {
    const double left = 80, right = 30, top = 50, bottom = 110;
    const double pw = width - left - right, ph = height - top - bottom;
    const double y_min = d.y_min, y_max = d.y_max > d.y_min ? d.y_max : d.y_min + 1.0;
    auto y_of = [&](double v) { return top + ph * (1.0 - (std::clamp(v, y_min, y_max) - y_min) / (y_max - y_min)); };

    const PlotArea area{left, top, pw, ph};

    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);

    // Grid and y axis labels: 10 steps of a round size (10 % for percent).
    draw_y_grid(cr, area, y_min, y_max, tick_step(y_max - y_min, 10), y_of,
                [](double v) { return fmt::format("{:g}", v); });
    draw_axes(cr, area);

    // Means with CI whiskers.
    const std::size_t k = d.conditions.size();
    const double step = k ? pw / double(k) : pw;
    for (std::size_t j = 0; j < k; ++j) {
        const double x = left + step * (double(j) + 0.5);
        const double bar_w = std::min(60.0, step * 0.6);
        cairo_set_source_rgb(cr, 0.35, 0.55, 0.8);
        const double base = std::clamp(0.0, y_min, y_max);  // bars grow from 0 (or the axis end)
        cairo_rectangle(cr, x - bar_w / 2, y_of(d.means[j]), bar_w, y_of(base) - y_of(d.means[j]));
        cairo_fill(cr);
        cairo_set_source_rgb(cr, 0, 0, 0);
        cairo_set_line_width(cr, 1.5);
        cairo_move_to(cr, x, y_of(d.ci_low[j]));
        cairo_line_to(cr, x, y_of(d.ci_high[j]));
        for (double v : {d.ci_low[j], d.ci_high[j]}) {
            cairo_move_to(cr, x - 8, y_of(v));
            cairo_line_to(cr, x + 8, y_of(v));
        }
        cairo_stroke(cr);
        // Condition label, rotated when long.
        cairo_set_font_size(cr, 12);
        cairo_text_extents_t ext;
        cairo_text_extents(cr, d.conditions[j].c_str(), &ext);
        cairo_save(cr);
        if (ext.width > step - 6) {
            cairo_move_to(cr, x, top + ph + 14);
            cairo_rotate(cr, M_PI / 6);
        } else {
            cairo_move_to(cr, x - ext.width / 2, top + ph + 18);
        }
        cairo_show_text(cr, d.conditions[j].c_str());
        cairo_restore(cr);
    }

    draw_titles(cr, area, d.title, d.y_label, d.caption, height - 12);
}

void check(cairo_status_t status, const std::filesystem::path& path) {
    if (status != CAIRO_STATUS_SUCCESS)
        throw InputError(path, fmt::format("cannot write the plot: {}", cairo_status_to_string(status)));
}

}  // namespace

void write_plot_png(const std::filesystem::path& path, const PlotData& data, int width, int height) {
    AVSI_ASSERT(data.means.size() == data.conditions.size());
    cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height);
    cairo_t* cr = cairo_create(surface);
    draw(cr, data, width, height);
    cairo_destroy(cr);
    const cairo_status_t status = cairo_surface_write_to_png(surface, path.c_str());
    cairo_surface_destroy(surface);
    check(status, path);
}

void write_plot_svg(const std::filesystem::path& path, const PlotData& data, int width, int height) {
    AVSI_ASSERT(data.means.size() == data.conditions.size());
    cairo_surface_t* surface = cairo_svg_surface_create(path.c_str(), width, height);
    cairo_t* cr = cairo_create(surface);
    draw(cr, data, width, height);
    cairo_destroy(cr);
    cairo_surface_finish(surface);
    const cairo_status_t status = cairo_surface_status(surface);
    cairo_surface_destroy(surface);
    check(status, path);
}

}  // namespace avsi::analysis::detail
