// The marker fit's residual per marker and frame: a CSV and a plot
// (marker_fit.h).
#include <cmath>

#include "avsi/core/csv.h"
#include "avsi/core/files.h"
#include "avsi/learn/marker_fit.h"
#include "svg_plot.h"

namespace avsi::learn {
namespace {

// Per frame, the RMS and the largest residual over the markers seen (NaN: none).
std::pair<std::vector<double>, std::vector<double>> frame_residuals(const MarkerFitResult& fit) {
    const std::size_t frames = fit.track.size(), n = fit.markers.size();
    std::vector<double> rms(frames, std::nan("")), worst(frames, std::nan(""));
    for (std::size_t f = 0; f < frames; ++f) {
        double sq = 0, mx = 0;
        std::size_t seen = 0;
        for (std::size_t m = 0; m < n; ++m) {
            const double r = fit.residual(f, m);
            if (!std::isfinite(r)) continue;
            sq += r * r;
            mx = std::max(mx, r);
            ++seen;
        }
        if (seen) rms[f] = std::sqrt(sq / double(seen)), worst[f] = mx;
    }
    return {rms, worst};
}

// Per marker, the RMS residual over the frames it was seen in.
std::vector<double> marker_rms(const MarkerFitResult& fit) {
    std::vector<double> out;
    for (std::size_t m = 0; m < fit.markers.size(); ++m) {
        double sq = 0;
        std::size_t seen = 0;
        for (std::size_t f = 0; f < fit.track.size(); ++f)
            if (std::isfinite(fit.residual(f, m))) sq += fit.residual(f, m) * fit.residual(f, m), ++seen;
        out.push_back(seen ? std::sqrt(sq / double(seen)) : std::nan(""));
    }
    return out;
}

}  // namespace

void write_fit_residuals_csv(const std::filesystem::path& path, const MarkerFitResult& fit) {
    std::vector<std::string> header{"time_s"};
    for (const auto& m : fit.markers) header.push_back(m);
    std::string out = csv_line(header);
    for (std::size_t f = 0; f < fit.track.size(); ++f) {
        out += fmt::format("{:.6f}", fit.track.time_s(f));
        for (std::size_t m = 0; m < fit.markers.size(); ++m) {
            const double r = fit.residual(f, m);
            out += std::isfinite(r) ? fmt::format(",{:.4f}", r) : std::string(",");
        }
        out += '\n';
    }
    write_text_file(path, out);
}

void write_fit_residual_plot(const std::filesystem::path& path, const MarkerFitResult& fit, const std::string& title) {
    const auto residuals = frame_residuals(fit);
    const std::vector<double>& rms = residuals.first;
    const std::vector<double>& worst = residuals.second;
    const std::vector<double> per_marker = marker_rms(fit);
    detail::ValueRange range;
    range.extend(0.0);
    for (double v : worst) range.extend(v);
    for (double v : per_marker) range.extend(v);
    const auto padded = range.padded(0.05);
    const double lo = padded.first, hi = padded.second;
    const detail::PlotBox box{820, 300, 50, 230, 30, 30};
    detail::SvgPage page(path, box);
    cairo_t* cr = page.cr();
    page.frame_with_value_labels(lo, hi, 40);
    page.text(box.left, 18, title + " — residual (mm) per frame: RMS (blue), largest (grey); per marker RMS (right)");
    const std::size_t frames = rms.size();
    auto x = [&](std::size_t k) { return page.x_of(double(k), 0.0, double(std::max<std::size_t>(frames, 2) - 1)); };
    cairo_set_line_width(cr, 0.8);
    cairo_set_source_rgb(cr, 0.6, 0.6, 0.6);
    page.polyline(frames, x, [&](std::size_t k) { return std::isfinite(worst[k]) ? page.y_of(worst[k], lo, hi) : NAN; });
    cairo_set_source_rgb(cr, 0.1, 0.3, 0.8);
    page.polyline(frames, x, [&](std::size_t k) { return std::isfinite(rms[k]) ? page.y_of(rms[k], lo, hi) : NAN; });
    // The markers' RMS as horizontal bars right of the frame.
    const double bar_left = box.width - box.right + 60, row = std::min(12.0, box.frame_height() / double(std::max<std::size_t>(per_marker.size(), 1)));
    cairo_set_font_size(cr, std::max(6.0, row - 2));
    for (std::size_t m = 0; m < per_marker.size(); ++m) {
        const double y = box.top + row * double(m);
        cairo_set_source_rgb(cr, 0, 0, 0);
        page.text(box.width - box.right + 8, y + row - 2, fit.markers[m]);
        if (!std::isfinite(per_marker[m])) continue;
        cairo_set_source_rgb(cr, 0.1, 0.3, 0.8);
        cairo_rectangle(cr, bar_left, y + 1, (box.right - 70) * per_marker[m] / hi, row - 2);
        cairo_fill(cr);
    }
    page.finish();
}

}  // namespace avsi::learn
