// Pairwise comparisons: paired (Fisher LSD as in the study) and pooled-error
// LSD t-tests, Holm and Bonferroni adjustments, CIs and d_z. See pairwise.h.
#include "avsi/analysis/pairwise.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "avsi/core/error.h"

namespace avsi::analysis {

std::vector<std::optional<double>> bonferroni_adjust(const std::vector<std::optional<double>>& p) {
    const double m = double(std::count_if(p.begin(), p.end(), [](const auto& v) { return v.has_value(); }));
    std::vector<std::optional<double>> out(p.size());
    for (std::size_t i = 0; i < p.size(); ++i)
        if (p[i]) out[i] = std::min(1.0, *p[i] * m);
    return out;
}

std::vector<std::optional<double>> holm_adjust(const std::vector<std::optional<double>>& p) {
    // R: i <- seq_len(n); o <- order(p); pmin(1, cummax((n - i + 1) * p[o]))[order(o)]
    std::vector<std::size_t> order;
    for (std::size_t i = 0; i < p.size(); ++i)
        if (p[i]) order.push_back(i);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return *p[a] < *p[b]; });
    const double m = double(order.size());
    std::vector<std::optional<double>> out(p.size());
    double running = 0.0;
    for (std::size_t r = 0; r < order.size(); ++r) {
        running = std::max(running, (m - double(r)) * *p[order[r]]);
        out[order[r]] = std::min(1.0, running);
    }
    return out;
}

PairwiseComparison paired_comparison(const WithinData& data, std::size_t a, std::size_t b, double confidence) {
    const std::size_t n = data.n();
    AVSI_ASSERT(n >= 2 && a < data.k() && b < data.k());
    PairwiseComparison c;
    c.a = data.conditions[a];
    c.b = data.conditions[b];
    c.index_a = a;
    c.index_b = b;
    double mean = 0.0;
    for (std::size_t i = 0; i < n; ++i) mean += data.at(i, a) - data.at(i, b);
    mean /= double(n);
    double ss = 0.0;
    for (std::size_t i = 0; i < n; ++i) ss += std::pow(data.at(i, a) - data.at(i, b) - mean, 2);
    c.mean_difference = mean;
    c.sd_difference = std::sqrt(ss / double(n - 1));
    c.df = double(n - 1);
    const double se = c.sd_difference / std::sqrt(double(n));
    const double crit = t_quantile_upper(1.0 - confidence, c.df);
    c.ci_low = mean - crit * se;
    c.ci_high = mean + crit * se;
    // R's t.test refuses "essentially constant" differences; so do we.
    if (c.sd_difference > 1e-12 * std::max(1.0, std::fabs(mean))) {
        c.t = mean / se;
        c.p_value = t_two_sided_p(*c.t, c.df);
        c.d_z = mean / c.sd_difference;
    }
    return c;
}

std::vector<PairwiseComparison> pairwise_comparisons(const WithinData& data, const AnovaResult& anova,
                                                     const PairwiseSettings& settings) {
    std::vector<PairwiseComparison> out;
    const std::size_t n = data.n();
    for (std::size_t a = 0; a < data.k(); ++a)
        for (std::size_t b = a + 1; b < data.k(); ++b) {
            PairwiseComparison c = paired_comparison(data, a, b, settings.confidence);
            c.df_pooled = anova.df_error;
            const double se = std::sqrt(2.0 * anova.ms_error / double(n));
            const double crit = t_quantile_upper(1.0 - settings.confidence, c.df_pooled);
            c.ci_pooled_low = c.mean_difference - crit * se;
            c.ci_pooled_high = c.mean_difference + crit * se;
            if (se > 0) {
                c.t_pooled = c.mean_difference / se;
                c.p_pooled = t_two_sided_p(*c.t_pooled, c.df_pooled);
            }
            out.push_back(std::move(c));
        }
    std::vector<std::optional<double>> p, p_pooled;
    for (const auto& c : out) {
        p.push_back(c.p_value);
        p_pooled.push_back(c.p_pooled);
    }
    const auto holm = holm_adjust(p), bonf = bonferroni_adjust(p);
    const auto holm_pooled = holm_adjust(p_pooled), bonf_pooled = bonferroni_adjust(p_pooled);
    for (std::size_t i = 0; i < out.size(); ++i) {
        out[i].p_holm = holm[i];
        out[i].p_bonferroni = bonf[i];
        out[i].p_pooled_holm = holm_pooled[i];
        out[i].p_pooled_bonferroni = bonf_pooled[i];
    }
    return out;
}

}  // namespace avsi::analysis
