// Information transmitted by a count table (information.h).
#include "avsi/core/information.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace avsi {

namespace {

double entropy_bits(const std::vector<double>& counts, double n) {
    double h = 0.0;
    for (double c : counts)
        if (c > 0.0) h -= (c / n) * std::log2(c / n);
    return h;
}

std::size_t occupied(const std::vector<double>& counts) {
    return static_cast<std::size_t>(std::count_if(counts.begin(), counts.end(), [](double c) { return c > 0.0; }));
}

}  // namespace

Transmission information_transmitted(const std::vector<std::vector<double>>& counts) {
    Transmission t;
    std::vector<double> px, py, pxy;
    for (std::size_t i = 0; i < counts.size(); ++i) {
        px.push_back(0.0);
        for (std::size_t j = 0; j < counts[i].size(); ++j) {
            if (py.size() <= j) py.resize(j + 1, 0.0);
            px[i] += counts[i][j];
            py[j] += counts[i][j];
            pxy.push_back(counts[i][j]);
            t.n += counts[i][j];
        }
    }
    if (t.n <= 0.0) return t;
    t.h_x = entropy_bits(px, t.n);
    const double h_y = entropy_bits(py, t.n), h_xy = entropy_bits(pxy, t.n);
    t.t_plugin = std::max(0.0, t.h_x + h_y - h_xy);  // ≥ 0 but for rounding
    const double per_bin = 1.0 / (2.0 * t.n * std::log(2.0));
    const double m_x = double(occupied(px)), m_y = double(occupied(py)), m_xy = double(occupied(pxy));
    t.h_x_corrected = t.h_x + (m_x - 1.0) * per_bin;
    t.t_corrected = t.t_plugin - (m_xy - m_x - m_y + 1.0) * per_bin;
    t.rti = t.h_x_corrected > 0.0 ? t.t_corrected / t.h_x_corrected : 0.0;
    return t;
}

}  // namespace avsi
