// Shared figure parts (see plot_axes.h).
#include "plot_axes.h"

#include <algorithm>
#include <cmath>

namespace avsi::analysis::detail {

double tick_step(double range, int wanted) {
    const double raw = range / std::max(1, wanted);
    const double p = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * p) return m * p;
    return 10 * p;
}

void draw_y_grid(cairo_t* cr, const PlotArea& area, double from, double to, double step,
                 const std::function<double(double)>& y_of, const std::function<std::string(double)>& label) {
    cairo_set_font_size(cr, 12);
    for (double v = std::ceil(from / step - 1e-9) * step; v <= to + 1e-6 * step; v += step) {
        const double y = y_of(v);
        cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
        cairo_set_line_width(cr, 1);
        cairo_move_to(cr, area.left, y);
        cairo_line_to(cr, area.left + area.width, y);
        cairo_stroke(cr);
        const std::string text = label(std::fabs(v) < 1e-9 * step ? 0.0 : v);
        cairo_text_extents_t ext;
        cairo_text_extents(cr, text.c_str(), &ext);
        cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
        cairo_move_to(cr, area.left - 8 - ext.width, y + ext.height / 2);
        cairo_show_text(cr, text.c_str());
    }
}

void draw_axes(cairo_t* cr, const PlotArea& area) {
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_line_width(cr, 1.5);
    cairo_move_to(cr, area.left, area.top);
    cairo_line_to(cr, area.left, area.top + area.height);
    cairo_line_to(cr, area.left + area.width, area.top + area.height);
    cairo_stroke(cr);
}

void draw_titles(cairo_t* cr, const PlotArea& area, const std::string& title, const std::string& y_label,
                 const std::string& caption, double caption_y) {
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_font_size(cr, 16);
    cairo_move_to(cr, area.left, 30);
    cairo_show_text(cr, title.c_str());
    cairo_set_font_size(cr, 13);
    cairo_save(cr);
    cairo_text_extents_t ext;
    cairo_text_extents(cr, y_label.c_str(), &ext);
    cairo_move_to(cr, 24, area.top + area.height / 2 + ext.width / 2);
    cairo_rotate(cr, -M_PI / 2);
    cairo_show_text(cr, y_label.c_str());
    cairo_restore(cr);
    cairo_set_font_size(cr, 11);
    cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
    cairo_move_to(cr, area.left, caption_y);
    cairo_show_text(cr, caption.c_str());
}

}  // namespace avsi::analysis::detail
