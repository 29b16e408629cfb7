// The one plot helper of learn's figures (Fig. 5 target-vs-model tracks in
// evaluation.cpp, the Fig. 4 look-ahead sweep in ann_command.cpp): the value
// range of the plotted data, a cairo SVG surface with a white background and
// an 11 px sans-serif font, positions on the plot frame, the frame with five
// value labels, text, lines broken at missing values, and cairo's write
// errors reported as InputError when the page is finished. (cairo is
// learn's: synth's own `avsi synth --plot` writes its SVG as text.)
#pragma once

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include <cairo-svg.h>
#include <cairo.h>
#include <fmt/format.h>

#include "avsi/core/error.h"

namespace avsi::learn::detail {

// The range of the finite values given to extend(), widened for plotting.
class ValueRange {
public:
    void extend(double v) {
        if (std::isfinite(v)) {
            m_lo = std::min(m_lo, v);
            m_hi = std::max(m_hi, v);
        }
    }
    // [lo, hi] with pad_fraction of its width added on each side (a range of
    // one value first widened by 0.5 each way).
    std::pair<double, double> padded(double pad_fraction) const {
        double lo = m_lo, hi = m_hi;
        if (!(hi > lo)) {
            lo -= 0.5;
            hi += 0.5;
        }
        const double pad = pad_fraction * (hi - lo);
        return {lo - pad, hi + pad};
    }

private:
    double m_lo = std::numeric_limits<double>::infinity();
    double m_hi = -std::numeric_limits<double>::infinity();
};

// Page size and the margins around the plot frame, in SVG points.
struct PlotBox {
    double width = 0, height = 0, left = 0, right = 0, top = 0, bottom = 0;
    double frame_width() const { return width - left - right; }
    double frame_height() const { return height - top - bottom; }
};

class SvgPage {
public:
    // Creates the file's folder and the surface; nothing is checked until finish().
    SvgPage(const std::filesystem::path& path, const PlotBox& box) : m_path(path), m_box(box) {
        if (!path.parent_path().empty()) std::filesystem::create_directories(path.parent_path());
        m_surface = cairo_svg_surface_create(path.c_str(), box.width, box.height);
        m_cr = cairo_create(m_surface);
        cairo_set_source_rgb(m_cr, 1, 1, 1);
        cairo_paint(m_cr);
        cairo_select_font_face(m_cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
        cairo_set_font_size(m_cr, 11);
    }
    SvgPage(const SvgPage&) = delete;
    SvgPage& operator=(const SvgPage&) = delete;
    ~SvgPage() { release(); }

    cairo_t* cr() const { return m_cr; }

    // Horizontal position of value v on a frame spanning [lo, hi] left to right.
    double x_of(double v, double lo, double hi) const {
        return m_box.left + (v - lo) / (hi - lo) * m_box.frame_width();
    }

    // Vertical position of value v on a frame spanning [lo, hi] bottom to top.
    double y_of(double v, double lo, double hi) const {
        return m_box.top + (hi - v) / (hi - lo) * m_box.frame_height();
    }

    // The black frame and five labels lo … hi ("{:.2f}") at label_inset left of it.
    void frame_with_value_labels(double lo, double hi, double label_inset) {
        cairo_set_source_rgb(m_cr, 0, 0, 0);
        cairo_set_line_width(m_cr, 1);
        cairo_rectangle(m_cr, m_box.left, m_box.top, m_box.frame_width(), m_box.frame_height());
        cairo_stroke(m_cr);
        for (int i = 0; i <= 4; ++i) {
            const double v = lo + (hi - lo) * i / 4.0;
            cairo_move_to(m_cr, m_box.left - label_inset, y_of(v, lo, hi) + 4);
            cairo_show_text(m_cr, fmt::format("{:.2f}", v).c_str());
        }
    }

    // `text` with its baseline starting at (x, y), in the current colour.
    void text(double x, double y, const std::string& text) {
        cairo_move_to(m_cr, x, y);
        cairo_show_text(m_cr, text.c_str());
    }

    // A line through (x(k), y(k)) for k < count, lifted where y(k) is not
    // finite, stroked in the current colour and width.
    template <class X, class Y>
    void polyline(std::size_t count, const X& x, const Y& y) {
        bool pen = false;
        for (std::size_t k = 0; k < count; ++k) {
            const double yk = y(k);
            if (!std::isfinite(yk)) {
                pen = false;
                continue;
            }
            if (pen)
                cairo_line_to(m_cr, x(k), yk);
            else
                cairo_move_to(m_cr, x(k), yk);
            pen = true;
        }
        cairo_stroke(m_cr);
    }

    // Writes the file; throws InputError naming it when cairo could not.
    void finish() {
        cairo_destroy(m_cr);
        m_cr = nullptr;
        cairo_surface_finish(m_surface);
        const cairo_status_t status = cairo_surface_status(m_surface);
        release();
        if (status != CAIRO_STATUS_SUCCESS)
            throw InputError(m_path, fmt::format("cannot write the SVG plot: {}", cairo_status_to_string(status)));
    }

private:
    void release() {
        if (m_cr) cairo_destroy(m_cr);
        if (m_surface) cairo_surface_destroy(m_surface);
        m_cr = nullptr;
        m_surface = nullptr;
    }

    std::filesystem::path m_path;
    PlotBox m_box;
    cairo_surface_t* m_surface = nullptr;
    cairo_t* m_cr = nullptr;
};

}  // namespace avsi::learn::detail
