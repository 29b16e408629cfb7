// Cousineau-Morey within-subject confidence intervals (Cousineau 2005; Morey 2008).
#include "avsi/analysis/descriptives.h"

#include <cmath>

#include "avsi/analysis/rm_anova.h"

namespace avsi::analysis {

std::vector<ConditionSummary> describe(const WithinData& data, double confidence) {
    const std::size_t n = data.n(), k = data.k();
    std::vector<double> subject_mean(n, 0.0);
    double grand = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = 0; j < k; ++j) subject_mean[i] += data.at(i, j) / double(k);
        grand += subject_mean[i] / double(n);
    }
    const double morey = std::sqrt(double(k) / double(k - 1));
    const double crit = t_quantile_upper(1.0 - confidence, double(n - 1));
    std::vector<ConditionSummary> out;
    for (std::size_t j = 0; j < k; ++j) {
        ConditionSummary s;
        s.condition = data.conditions[j];
        s.n = n;
        for (std::size_t i = 0; i < n; ++i) s.mean += data.at(i, j) / double(n);
        double ss = 0.0, ss_norm = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            ss += std::pow(data.at(i, j) - s.mean, 2);
            // normalised score y - subject mean + grand mean has the same mean
            ss_norm += std::pow(data.at(i, j) - subject_mean[i] + grand - s.mean, 2);
        }
        s.sd = std::sqrt(ss / double(n - 1));
        s.se_within = morey * std::sqrt(ss_norm / double(n - 1)) / std::sqrt(double(n));
        s.ci_low = s.mean - crit * s.se_within;
        s.ci_high = s.mean + crit * s.se_within;
        out.push_back(s);
    }
    return out;
}

}  // namespace avsi::analysis
