// Per-condition descriptives with within-subject confidence intervals:
// Cousineau (2005) normalisation y'_ij = y_ij - mean_i + grand mean, with
// Morey's (2008) correction sqrt(k / (k - 1)) of the standard error; the CI is
// mean ± t(1 - alpha/2, n - 1) · se_morey.
#pragma once

#include <string>
#include <vector>

#include "avsi/analysis/scores.h"

namespace avsi::analysis {

struct ConditionSummary {
    std::string condition;
    std::size_t n = 0;
    double mean = 0.0;
    double sd = 0.0;              // between-subject SD
    double se_within = 0.0;       // Cousineau-Morey standard error
    double ci_low = 0.0, ci_high = 0.0;  // within-subject CI
};

// One row per condition, in condition order.
std::vector<ConditionSummary> describe(const WithinData& data, double confidence = 0.95);

}  // namespace avsi::analysis
