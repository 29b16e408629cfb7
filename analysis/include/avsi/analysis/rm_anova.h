// One-way repeated-measures ANOVA (one within-subject factor, k conditions,
// n subjects) with Mauchly's sphericity test and the Greenhouse-Geisser and
// Huynh-Feldt corrections, computed as R does:
//   * sums of squares and F as base aov(y ~ condition + Error(subject/condition));
//   * Mauchly's W = det(T'ST) / (tr(T'ST)/p)^p for orthonormal contrasts T
//     (p = k - 1) and its p value from stats:::mauchly.test.SSD, including the
//     second-order term w2 (which R writes with the number of conditions k in
//     "3 * k + 2");
//   * GG epsilon = (sum lambda)^2 / (p * sum lambda^2), lambda the eigenvalues
//     of T'ST (Box 1954; stats:::sphericity, car);
//   * HF epsilon = (n p eps_GG - 2) / (p (n - 1 - p eps_GG)) (Huynh & Feldt
//     1976; identical to the Lecoutre 1991 form for one group of subjects, as
//     stats:::sphericity and car compute it). The raw value is reported; the
//     corrected p uses min(1, eps_HF), as car does;
//   * partial eta^2 = SS_c / (SS_c + SS_e); generalised eta^2 (Olejnik & Algina
//     2003) = SS_c / (SS_c + SS_subjects + SS_e).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/scores.h"

namespace avsi::analysis {

// Mauchly's test of sphericity.
struct Mauchly {
    bool computable = true;  // false when T'ST is singular (W = 0): no chi-square
    double W = 1.0;
    std::optional<double> chisq;  // -n rho log W
    std::optional<double> df;     // p (p + 1) / 2 - 1
    std::optional<double> p_value;
    std::string note;  // why it is trivial or not computable
};

// A sphericity correction: epsilon, corrected dfs and p.
struct Correction {
    std::optional<double> epsilon;  // raw value (HF may exceed 1)
    double df_conditions = 0.0;     // with min(1, epsilon) applied
    double df_error = 0.0;
    std::optional<double> p_value;
};

struct AnovaResult {
    std::size_t n = 0;  // subjects in the analysis
    std::size_t k = 0;  // conditions
    double ss_conditions = 0.0, ss_subjects = 0.0, ss_error = 0.0, ss_total = 0.0;
    double df_conditions = 0.0, df_subjects = 0.0, df_error = 0.0;
    double ms_conditions = 0.0, ms_error = 0.0;
    std::optional<double> F;        // nullopt when MS_error = 0
    std::optional<double> p_value;  // upper tail of F(df_c, df_e)
    double partial_eta_sq = 0.0;
    double generalized_eta_sq = 0.0;
    Mauchly mauchly;
    Correction greenhouse_geisser;
    Correction huynh_feldt;
    Correction lower_bound;  // epsilon = 1 / (k - 1)
    std::vector<WithinData::Dropped> dropped;  // subjects removed listwise
    std::vector<std::string> notes;
};

// Runs the ANOVA on complete data (n >= 2, k >= 2).
AnovaResult rm_anova(const WithinData& data);

// Upper-tail p of F(df1, df2) at f, finite and > 0 whenever representable.
double f_upper_p(double f, double df1, double df2);
// Two-sided p of Student's t with df degrees of freedom.
double t_two_sided_p(double t, double df);
// The (1 - alpha/2) quantile of Student's t.
double t_quantile_upper(double alpha, double df);

}  // namespace avsi::analysis
