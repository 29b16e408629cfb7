# Reference values for the analysis module's R agreement tests.
# For every tests/data/analysis/<case>.csv (scores.csv format) this computes,
# with base R (aov with an Error term, mauchly.test, stats:::sphericity,
# t.test), car/afex (aov_ez -> car::Anova univariate tests) and emmeans, the
# numbers avsi must reproduce, and writes tests/data/analysis/<case>.expected.json.
# Usage (from the repository root): Rscript scripts/r/reference.R [case ...]
suppressPackageStartupMessages({
  library(afex)
  library(car)
  library(emmeans)
  library(jsonlite)
})
options(contrasts = c("contr.sum", "contr.poly"))
dir <- "tests/data/analysis"
args <- commandArgs(trailingOnly = TRUE)
cases <- if (length(args)) args else sub("\\.csv$", "", list.files(dir, pattern = "^[a-z0-9_]+\\.csv$"))

num <- function(x) if (is.null(x) || length(x) == 0 || is.na(x)) NA else unname(as.numeric(x))

reference <- function(case) {
  d <- read.csv(file.path(dir, paste0(case, ".csv")), stringsAsFactors = FALSE,
                na.strings = c("NA", ""))
  levels_c <- unique(d$condition)
  levels_s <- unique(d$subject)
  # Listwise deletion: keep subjects with a score in every condition.
  complete <- sapply(levels_s, function(s) {
    x <- d[d$subject == s, ]
    all(levels_c %in% x$condition[!is.na(x$percent)])
  })
  dropped <- levels_s[!complete]
  d <- d[d$subject %in% levels_s[complete], ]
  d$subject <- factor(d$subject, levels = levels_s[complete])
  d$condition <- factor(d$condition, levels = levels_c)
  k <- length(levels_c)
  n <- nlevels(d$subject)

  # Base R: aov with an Error stratum.
  fit <- aov(percent ~ condition + Error(subject / condition), data = d)
  s <- summary(fit)
  within <- s[["Error: subject:condition"]][[1]]
  between <- s[["Error: subject"]][[1]]
  out <- list(case = case, n = n, k = k, dropped = as.list(dropped),
              ss_conditions = within["condition", "Sum Sq"],
              ss_error = within["Residuals", "Sum Sq"],
              ss_subjects = between["Residuals", "Sum Sq"],
              df_conditions = within["condition", "Df"],
              df_error = within["Residuals", "Df"],
              F = within["condition", "F value"],
              p = within["condition", "Pr(>F)"])

  # Wide matrix, multivariate model and the stats sphericity functions.
  Y <- sapply(levels_c, function(cn) d$percent[d$condition == cn][order(d$subject[d$condition == cn])])
  mlm <- lm(Y ~ 1)
  sph <- stats:::sphericity(SSD(mlm), X = ~1)
  out$gg_epsilon <- sph$GG.eps
  out$hf_epsilon <- sph$HF.eps
  out$gg_p <- pf(out$F, sph$GG.eps * out$df_conditions, sph$GG.eps * out$df_error, lower.tail = FALSE)
  hf <- min(1, sph$HF.eps)
  out$hf_p <- pf(out$F, hf * out$df_conditions, hf * out$df_error, lower.tail = FALSE)
  if (k > 2) {
    m <- mauchly.test(mlm, X = ~1)
    out$mauchly_W <- num(m$statistic)
    out$mauchly_p <- num(m$p.value)
  } else {
    out$mauchly_W <- 1
    out$mauchly_p <- NA
  }

  # afex (car::Anova underneath): effect sizes and, where car computes them,
  # the sphericity table. car marks singular error SSP matrices as NA.
  a <- suppressWarnings(suppressMessages(aov_ez("subject", "percent", d, within = "condition",
                                                anova_table = list(correction = "none", es = c("pes", "ges")))))
  at <- a$anova_table
  out$afex_F <- num(at$F)
  out$afex_p <- num(at$`Pr(>F)`)
  out$pes <- num(at$pes)
  out$ges <- num(at$ges)
  sa <- suppressWarnings(summary(a))
  if (k > 2 && nrow(sa$sphericity.tests) > 0) {
    out$car_mauchly_W <- num(sa$sphericity.tests[1, "Test statistic"])
    out$car_mauchly_p <- num(sa$sphericity.tests[1, "p-value"])
  }
  if (k > 2 && nrow(sa$pval.adjustments) > 0) {
    out$car_gg_epsilon <- num(sa$pval.adjustments[1, "GG eps"])
    out$car_gg_p <- num(sa$pval.adjustments[1, "Pr(>F[GG])"])
    out$car_hf_epsilon <- num(sa$pval.adjustments[1, "HF eps"])
    out$car_hf_p <- num(sa$pval.adjustments[1, "Pr(>F[HF])"])
  }

  # Pairwise: paired t-tests (Fisher LSD as in the study), Holm/Bonferroni.
  pairs_out <- list()
  pvals <- c()
  for (i in 1:(k - 1)) for (j in (i + 1):k) {
    x <- Y[, i]; y <- Y[, j]
    tt <- tryCatch(t.test(x, y, paired = TRUE), error = function(e) NULL)
    diff <- x - y
    pairs_out[[length(pairs_out) + 1]] <- list(
      a = levels_c[i], b = levels_c[j], mean_difference = mean(diff),
      t = if (is.null(tt)) NA else num(tt$statistic),
      df = n - 1,
      p = if (is.null(tt)) NA else num(tt$p.value),
      ci_low = if (is.null(tt)) NA else tt$conf.int[1],
      ci_high = if (is.null(tt)) NA else tt$conf.int[2],
      d_z = if (sd(diff) > 0) mean(diff) / sd(diff) else NA)
    pvals <- c(pvals, if (is.null(tt)) NA else tt$p.value)
  }
  holm <- p.adjust(pvals, "holm")
  bonf <- p.adjust(pvals, "bonferroni")
  # Pooled-error LSD: emmeans on the aov fit (within-stratum error).
  em <- suppressMessages(emmeans(fit, ~condition))
  pe <- as.data.frame(summary(pairs(em, adjust = "none"), infer = c(TRUE, TRUE)))
  for (r in seq_along(pairs_out)) {
    pairs_out[[r]]$p_holm <- holm[r]
    pairs_out[[r]]$p_bonferroni <- bonf[r]
    pairs_out[[r]]$t_pooled <- pe$t.ratio[r]
    pairs_out[[r]]$df_pooled <- pe$df[r]
    pairs_out[[r]]$p_pooled <- pe$p.value[r]
    pairs_out[[r]]$ci_pooled_low <- pe$lower.CL[r]
    pairs_out[[r]]$ci_pooled_high <- pe$upper.CL[r]
  }
  out$pairwise <- pairs_out
  out$generated_by <- paste(R.version.string, "; afex", packageVersion("afex"), "; car",
                            packageVersion("car"), "; emmeans", packageVersion("emmeans"))
  writeLines(toJSON(out, auto_unbox = TRUE, digits = I(17), na = "null", pretty = TRUE),
             file.path(dir, paste0(case, ".expected.json")))
  cat(case, ": F =", out$F, " p =", out$p, " W =", out$mauchly_W, " GG =", out$gg_epsilon,
      " HF =", out$hf_epsilon, "\n")
}

for (case in cases) reference(case)
