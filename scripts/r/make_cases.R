# Generates the input data sets (scores.csv format) for the R agreement tests
# of the analysis module: tests/data/analysis/<case>.csv.
# Usage (from the repository root): Rscript scripts/r/make_cases.R
# The inputs are committed; rerunning this script rewrites them identically.
out_dir <- "tests/data/analysis"
dir.create(out_dir, showWarnings = FALSE, recursive = TRUE)

# Keyword counts out of `keywords` per cell, as `avsi score` would produce.
simulate <- function(n, means, subject_sd, noise_sd, keywords = 45, seed,
                     condition_sd = NULL) {
  set.seed(seed)
  k <- length(means)
  if (is.null(condition_sd)) condition_sd <- rep(noise_sd, k)
  u <- rnorm(n, 0, subject_sd)
  rows <- list()
  for (i in seq_len(n)) for (j in seq_len(k)) {
    logit <- qlogis(means[j] / 100) + u[i] + rnorm(1, 0, condition_sd[j])
    correct <- rbinom(1, keywords, plogis(logit))
    rows[[length(rows) + 1]] <- data.frame(
      subject = sprintf("s%02d", i), condition = paste0("c", j),
      keywords = keywords, correct = correct, percent = 100 * correct / keywords)
  }
  do.call(rbind, rows)
}

write_case <- function(d, name) {
  d$percent <- ifelse(is.na(d$percent), "NA", sprintf("%.15g", d$percent))
  write.csv(d, file.path(out_dir, paste0(name, ".csv")), row.names = FALSE, quote = FALSE)
}

# 25 subjects x 6 conditions, like the reference study.
write_case(simulate(25, c(40, 48, 52, 55, 58, 62), 0.5, 0.3, seed = 2004), "balanced")

# Sphericity violated: one condition far noisier than the others.
write_case(simulate(18, c(45, 50, 55, 60), 0.4, 0.1, seed = 7,
                    condition_sd = c(0.05, 0.05, 0.9, 0.05)), "sphericity_violated")

# Two conditions: W = 1, epsilon = 1.
write_case(simulate(16, c(50, 60), 0.5, 0.3, seed = 11), "k2")

# Nearly spherical data with few subjects: Huynh-Feldt epsilon > 1.
d <- simulate(10, c(50, 52, 54), 0.6, 0.35, seed = 5, keywords = 1000)
write_case(d, "hf_above_one")

# Tied conditions: c3 is an exact copy of c2 for every subject, so the
# covariance of the contrasts is singular (W = 0).
d <- simulate(12, c(50, 60, 60, 70), 0.5, 0.3, seed = 3)
d[d$condition == "c3", c("correct", "percent")] <- d[d$condition == "c2", c("correct", "percent")]
write_case(d, "tied")

# Missing cells: s04 has no score in c2 (NA), s09 has no row for c3.
d <- simulate(14, c(45, 55, 50, 65), 0.5, 0.3, seed = 9)
d$percent[d$subject == "s04" & d$condition == "c2"] <- NA
d <- d[!(d$subject == "s09" & d$condition == "c3"), ]
write_case(d, "missing_cell")

# A huge effect: p far below 1e-80.
write_case(simulate(40, c(10, 30, 50, 70, 90), 0.2, 0.05, keywords = 200, seed = 1), "tiny_p")
