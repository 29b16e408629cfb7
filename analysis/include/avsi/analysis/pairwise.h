// Pairwise comparisons between conditions after the repeated-measures ANOVA:
//   * Fisher's LSD as in the reference study: uncorrected paired t-tests,
//     t = mean(d) / (sd(d) / sqrt(n)), df = n - 1 (R: t.test(paired = TRUE));
//   * the pooled-error LSD: t = diff / sqrt(2 MS_error / n), df = error df
//     (R: emmeans(..., model = "univariate"));
//   * Holm and Bonferroni adjustments of each family of p values
//     (R: p.adjust over the k (k - 1) / 2 pairs);
//   * mean difference with its 95 % CI and d_z = mean(d) / sd(d).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/rm_anova.h"
#include "avsi/analysis/scores.h"

namespace avsi::analysis {

struct PairwiseSettings {
    double confidence = 0.95;  // for the CI of the mean difference
};

// Condition a minus condition b.
struct PairwiseComparison {
    std::string a, b;
    std::size_t index_a = 0, index_b = 0;
    double mean_difference = 0.0;  // mean(a - b)
    double sd_difference = 0.0;
    // Paired (Fisher LSD as in the study).
    std::optional<double> t;
    double df = 0.0;
    std::optional<double> p_value;
    std::optional<double> p_holm, p_bonferroni;
    double ci_low = 0.0, ci_high = 0.0;
    std::optional<double> d_z;  // nullopt when sd(d) = 0
    // Pooled-error LSD.
    std::optional<double> t_pooled;
    double df_pooled = 0.0;
    std::optional<double> p_pooled;
    std::optional<double> p_pooled_holm, p_pooled_bonferroni;
    double ci_pooled_low = 0.0, ci_pooled_high = 0.0;
};

// All k (k - 1) / 2 pairs in condition order (1-2, 1-3, …, 2-3, …).
std::vector<PairwiseComparison> pairwise_comparisons(const WithinData& data, const AnovaResult& anova,
                                                     const PairwiseSettings& settings = {});

// One paired LSD comparison a - b (indices into data.conditions); fast path
// for simulations.
PairwiseComparison paired_comparison(const WithinData& data, std::size_t a, std::size_t b,
                                     double confidence = 0.95);

// Holm's step-down adjustment (R p.adjust "holm"); missing values are skipped
// and do not count towards the number of tests.
std::vector<std::optional<double>> holm_adjust(const std::vector<std::optional<double>>& p);
// Bonferroni adjustment (R p.adjust "bonferroni").
std::vector<std::optional<double>> bonferroni_adjust(const std::vector<std::optional<double>>& p);

}  // namespace avsi::analysis
