# Reference power for `avsi power` with a subject × condition random slope
# (tests/analysis/power_test.cpp, Power.RandomSlopeMatchesTheRReference).
# An independent simulation of the model in analysis/include/avsi/analysis/power.h:
#   logit P(correct) = logit(mean_c) + u_subject + v_sentence + w_subject,condition
#   u ~ N(0, subject_sd²), v ~ N(0, sentence_sd²), w ~ N(0, condition_sd²),
# k lists of `spc` sentences, list l shown to subject i in condition (l + i) mod k,
# `kw` Bernoulli keywords per sentence, percent correct per subject × condition;
# power of the repeated-measures F test (base aov with an Error stratum) and of
# the paired t-test of the last minus the first condition, at alpha.
# Writes tests/data/analysis/power_reference.json.
# Usage (from the repository root): Rscript scripts/r/power_reference.R
suppressPackageStartupMessages(library(jsonlite))
set.seed(3905)
means <- c(60, 64, 67); k <- length(means)
n <- 12; spc <- 15; kw <- 3
subject_sd <- 0.5; sentence_sd <- 0.5; alpha <- 0.05
sims <- 4000

one <- function(condition_sd) {
  u <- rnorm(n, 0, subject_sd)
  v <- matrix(rnorm(k * spc, 0, sentence_sd), nrow = k)  # v[list, sentence]
  w <- matrix(rnorm(n * k, 0, condition_sd), nrow = n)    # w[subject, condition]
  pct <- matrix(0, n, k)
  for (i in 1:n) for (l in 1:k) {
    cond <- ((l - 1) + (i - 1)) %% k + 1
    eta <- qlogis(means[cond] / 100) + u[i] + v[l, ] + w[i, cond]
    pct[i, cond] <- 100 * sum(rbinom(spc, kw, plogis(eta))) / (spc * kw)
  }
  d <- data.frame(subject = factor(rep(1:n, k)), condition = factor(rep(1:k, each = n)), y = as.vector(pct))
  s <- summary(aov(y ~ condition + Error(subject / condition), data = d))[["Error: subject:condition"]][[1]]
  p_anova <- s["condition", "Pr(>F)"]
  p_contrast <- t.test(pct[, k], pct[, 1], paired = TRUE)$p.value
  c(p_anova < alpha, p_contrast < alpha)
}

out <- list(means_percent = means, subjects = n, sentences_per_cell = spc, keywords_per_sentence = kw,
            subject_sd = subject_sd, sentence_sd = sentence_sd, alpha = alpha, simulations = sims,
            contrast = "c3 - c1", rows = list())
for (condition_sd in c(0, 0.95)) {
  r <- replicate(sims, one(condition_sd))
  pa <- mean(r[1, ]); pc <- mean(r[2, ])
  out$rows[[length(out$rows) + 1]] <- list(condition_sd = condition_sd, power_anova = pa,
                                           mc_se_anova = sqrt(pa * (1 - pa) / sims), power_contrast = pc,
                                           mc_se_contrast = sqrt(pc * (1 - pc) / sims))
  cat("condition SD", condition_sd, ": ANOVA", pa, " contrast", pc, "\n")
}
out$generated_by <- R.version.string
writeLines(toJSON(out, auto_unbox = TRUE, digits = I(17), pretty = TRUE), "tests/data/analysis/power_reference.json")
