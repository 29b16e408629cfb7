// One-way repeated-measures ANOVA with Mauchly's test and GG/HF corrections,
// reproducing R's stats (aov with Error, mauchly.test.SSD, sphericity) and car.
// See rm_anova.h for the formulas and their sources.
#include "avsi/analysis/rm_anova.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/Dense>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <boost/math/distributions/students_t.hpp>
#include <fmt/format.h>

#include "avsi/core/error.h"

namespace avsi::analysis {

double f_upper_p(double f, double df1, double df2) {
    AVSI_ASSERT(df1 > 0 && df2 > 0);
    if (!(f > 0)) return 1.0;
    if (std::isinf(f)) return 0.0;
    return boost::math::cdf(boost::math::complement(boost::math::fisher_f(df1, df2), f));
}

double t_two_sided_p(double t, double df) {
    AVSI_ASSERT(df > 0);
    if (std::isinf(t)) return 0.0;
    return 2.0 * boost::math::cdf(boost::math::complement(boost::math::students_t(df), std::fabs(t)));
}

double t_quantile_upper(double alpha, double df) {
    AVSI_ASSERT(df > 0 && alpha > 0 && alpha < 1);
    return boost::math::quantile(boost::math::complement(boost::math::students_t(df), alpha / 2.0));
}

namespace {

double chisq_upper_p(double x, double df) {
    if (std::isinf(x)) return 0.0;
    if (x <= 0) return 1.0;
    return boost::math::cdf(boost::math::complement(boost::math::chi_squared(df), x));
}

// (k - 1) × k orthonormal contrasts orthogonal to the unit vector (normalised
// Helmert). Mauchly's W and the epsilons do not depend on which orthonormal
// basis is used.
Eigen::MatrixXd helmert_contrasts(std::size_t k) {
    Eigen::MatrixXd T = Eigen::MatrixXd::Zero(Eigen::Index(k - 1), Eigen::Index(k));
    for (std::size_t r = 0; r + 1 < k; ++r) {
        const double j = double(r + 1);
        const double norm = std::sqrt(j * (j + 1.0));
        for (std::size_t c = 0; c <= r; ++c) T(Eigen::Index(r), Eigen::Index(c)) = 1.0 / norm;
        T(Eigen::Index(r), Eigen::Index(r + 1)) = -j / norm;
    }
    return T;
}

Correction make_correction(std::optional<double> epsilon, const AnovaResult& a) {
    Correction c;
    c.epsilon = epsilon;
    if (!epsilon) return c;
    const double e = std::min(1.0, *epsilon);
    c.df_conditions = e * a.df_conditions;
    c.df_error = e * a.df_error;
    if (a.F && c.df_conditions > 0 && c.df_error > 0) c.p_value = f_upper_p(*a.F, c.df_conditions, c.df_error);
    return c;
}

// Mauchly's test of sphericity from the eigenvalues of T SSD T' (all
// positive), for n subjects and k conditions.
void mauchly_test(const Eigen::VectorXd& lambda, std::size_t n, std::size_t k, Mauchly& m) {
    const double pp = double(k - 1);
    const double nn = double(n - 1);  // R: object$df
    const double sum = lambda.sum();
    // R: logW <- log(det(U)) - pp * log(Tr(U/pp)); rho, w2 and the
    // two chi-square tails exactly as stats:::mauchly.test.SSD.
    double log_det = 0.0;
    for (Eigen::Index i = 0; i < lambda.size(); ++i) log_det += std::log(lambda(i));
    const double log_w = log_det - pp * std::log(sum / pp);
    const double rho = 1.0 - (2.0 * pp * pp + pp + 2.0) / (6.0 * pp * nn);
    const double w2 = (pp + 2.0) * (pp - 1.0) * (pp - 2.0) *
                      (2.0 * pp * pp * pp + 6.0 * pp * pp + 3.0 * double(k) + 2.0) /
                      (288.0 * std::pow(nn * pp * rho, 2));
    const double z = -nn * rho * log_w;
    const double f = pp * (pp + 1.0) / 2.0 - 1.0;
    const double pr1 = chisq_upper_p(z, f);
    const double pr2 = chisq_upper_p(z, f + 4.0);
    m.W = std::exp(log_w);
    m.chisq = z;
    m.df = f;
    m.p_value = pr1 + w2 * (pr2 - pr1);  // unclamped, as R
}

}  // namespace

AnovaResult rm_anova(const WithinData& data) {
    const std::size_t n = data.n();
    const std::size_t k = data.k();
    AVSI_ASSERT(n >= 2 && k >= 2 && data.values.size() == n * k);
    AnovaResult a;
    a.n = n;
    a.k = k;
    a.dropped = data.dropped;

    // Step 1: means.
    std::vector<double> subject_mean(n, 0.0), condition_mean(k, 0.0);
    double grand = 0.0;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < k; ++j) {
            const double y = data.at(i, j);
            subject_mean[i] += y / double(k);
            condition_mean[j] += y / double(n);
            grand += y;
        }
    grand /= double(n * k);

    // Step 2: sums of squares. SS_error from the residuals directly (not by
    // subtraction) so it is exactly 0 for perfectly additive data.
    for (std::size_t j = 0; j < k; ++j) a.ss_conditions += double(n) * std::pow(condition_mean[j] - grand, 2);
    for (std::size_t i = 0; i < n; ++i) a.ss_subjects += double(k) * std::pow(subject_mean[i] - grand, 2);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < k; ++j) {
            const double y = data.at(i, j);
            a.ss_total += std::pow(y - grand, 2);
            a.ss_error += std::pow(y - subject_mean[i] - condition_mean[j] + grand, 2);
        }
    a.df_conditions = double(k - 1);
    a.df_subjects = double(n - 1);
    a.df_error = double((n - 1) * (k - 1));
    a.ms_conditions = a.ss_conditions / a.df_conditions;
    a.ms_error = a.ss_error / a.df_error;
    const double scale = std::max(a.ss_total, 1e-300);
    if (a.ss_error > 1e-14 * scale) {
        a.F = a.ms_conditions / a.ms_error;
        a.p_value = f_upper_p(*a.F, a.df_conditions, a.df_error);
    } else {
        a.notes.push_back("the error sum of squares is 0 (every subject differs from the condition means by a "
                          "constant): F and p are not defined");
    }
    a.partial_eta_sq = a.ss_conditions + a.ss_error > 0 ? a.ss_conditions / (a.ss_conditions + a.ss_error) : 0.0;
    const double ges_denominator = a.ss_conditions + a.ss_subjects + a.ss_error;
    a.generalized_eta_sq = ges_denominator > 0 ? a.ss_conditions / ges_denominator : 0.0;

    // Step 3: sphericity, on the (k-1) × (k-1) matrix T SSD T'.
    const std::size_t p = k - 1;
    std::optional<double> gg, hf;
    if (k == 2) {
        a.mauchly.W = 1.0;
        a.mauchly.p_value = 1.0;
        a.mauchly.note = "sphericity holds trivially with 2 conditions";
        gg = 1.0;
        hf = 1.0;
    } else {
        Eigen::MatrixXd Y(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(k));
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = 0; j < k; ++j) Y(Eigen::Index(i), Eigen::Index(j)) = data.at(i, j) - condition_mean[j];
        const Eigen::MatrixXd T = helmert_contrasts(k);
        const Eigen::MatrixXd Z = Y * T.transpose();           // n × p contrast scores
        const Eigen::MatrixXd U = Z.transpose() * Z;          // T SSD T'
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(U, Eigen::EigenvaluesOnly);
        const Eigen::VectorXd lambda = solver.eigenvalues();  // ascending
        const double lambda_max = lambda.maxCoeff();
        const double sum = lambda.sum();
        const double sum_sq = lambda.squaredNorm();
        if (lambda_max <= 0.0) {
            a.mauchly.computable = false;
            a.mauchly.W = 0.0;
            a.mauchly.note = "the contrast covariance is zero: sphericity cannot be assessed";
        } else {
            gg = sum * sum / (double(p) * sum_sq);
            const double nn = double(n - 1);  // R: object$df
            // Not estimable when n - 1 <= p * eps_GG (with n = 2 and one non-zero
            // eigenvalue it is 0/0): reported as such, never as a NaN.
            const double hf_denominator = double(p) * (nn - double(p) * *gg);
            if (hf_denominator > 0.0) hf = (double(n) * double(p) * *gg - 2.0) / hf_denominator;
            if (hf && !std::isfinite(*hf)) hf.reset();
            if (!hf)
                a.notes.push_back(fmt::format("Huynh-Feldt epsilon not estimable with {} subjects (n - 1 <= (k - 1) * "
                                              "Greenhouse-Geisser epsilon)",
                                              n));
            if (lambda.minCoeff() <= 1e-12 * lambda_max) {
                a.mauchly.computable = false;
                a.mauchly.W = 0.0;
                a.mauchly.note = n - 1 < p ? fmt::format("Mauchly's test is not computable: {} subjects are too few "
                                                         "for {} conditions (W = 0)", n, k)
                                           : "Mauchly's test is not computable: the covariance of the condition "
                                             "contrasts is singular (W = 0), e.g. tied conditions";
            } else {
                mauchly_test(lambda, n, k, a.mauchly);
            }
        }
    }
    a.greenhouse_geisser = make_correction(gg, a);
    a.huynh_feldt = make_correction(hf, a);
    a.lower_bound = make_correction(1.0 / double(k - 1), a);
    if (hf && *hf > 1.0) a.notes.push_back(fmt::format("Huynh-Feldt epsilon {:.4f} > 1 treated as 1", *hf));
    for (const auto& d : a.dropped)
        a.notes.push_back(fmt::format("subject {} dropped listwise (missing: {})", d.subject,
                                      fmt::join(d.missing_conditions, ", ")));
    return a;
}

}  // namespace avsi::analysis
