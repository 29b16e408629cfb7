// Information transmitted by a target × response count table (Miller &
// Nicely 1955), shared by the listeners' analysis (analysis/phoneme_information.h)
// and the objective viseme information of a stimulus set
// (stimuli/viseme_information.h), so both report one T and one RTI.
//
// From the pooled counts n_xy of N items, p = n / N:
//   T(x;y) = H(x) + H(y) − H(x,y)                         bits (plug-in, ≥ 0)
//   H(x)   = −Σ p(x) log2 p(x)
// with the Miller-Madow correction of each entropy (Miller 1955: the
// plug-in entropy of m occupied categories is low by (m − 1) / (2 N ln 2)):
//   T_MM = T − (m_xy − m_x − m_y + 1) / (2 N ln 2),   H_MM(x) = H(x) + (m_x − 1) / (2 N ln 2),
//   RTI  = T_MM / H_MM(x)   (0 when H_MM(x) is 0).
// Perfect transmission (m_xy = m_x = m_y) gives RTI exactly 1; independent
// rows and columns give T = 0 and T_MM ≤ 0 (kept as computed, not clamped).
#pragma once

#include <vector>

namespace avsi {

struct Transmission {
    double n = 0.0;
    double h_x = 0.0, t_plugin = 0.0;               // bits, plug-in
    double h_x_corrected = 0.0, t_corrected = 0.0;  // Miller-Madow
    double rti = 0.0;                               // t_corrected / h_x_corrected (0 when h_x is 0)
};

// T, H and RTI of a count table (rows: targets x, columns: responses y).
Transmission information_transmitted(const std::vector<std::vector<double>>& counts);

}  // namespace avsi
