# The SRT report's agreement-with-R case (tests/analysis/adaptive_report_test.cpp,
# AdaptiveReport.SphericityViolatedCaseMatchesR): 20 simulated listeners × 3
# conditions, each an adaptive sentence track of 20 sentences under avsi's
# default track rules (analysis/include/avsi/analysis/adaptive.h TrackSettings:
# start 0 dB, bounds ±30 dB, 4 dB steps after sentences 1–4 then 2 dB, first
# sentence repeated 4 dB higher until all keywords are right (at most 10
# times), SRT = mean of the levels of sentences 5..N plus the next level).
# The listeners' L50s make the differences between conditions unequally
# variable (av-b's benefit varies far more than av-a's): sphericity is violated.
#
# Writes, from the repository root:
#   tests/data/analysis/srt_sphericity.adaptive_trials.csv  (the tracks)
#   tests/data/analysis/srt_sphericity.expected.json        (R's numbers)
# The SRTs are computed here from the stored levels, independently of avsi;
# then afex::aov_ez (car's univariate tests with Mauchly, GG and HF), base
# aov, and the visual benefits (audio-only SRT minus the condition's) as
# paired t-tests with p.adjust Holm over the k − 1 benefits.
# Usage: Rscript scripts/r/srt_reference.R
suppressPackageStartupMessages({
  library(afex)
  library(car)
  library(jsonlite)
})
options(contrasts = c("contr.sum", "contr.poly"))
dir <- "tests/data/analysis"
case <- "srt_sphericity"
set.seed(3920)

keywords <- 3
sentences <- 20
slope <- 0.15  # proportion per dB at L50

# One track under the default rules; returns its presentations.
track <- function(l50) {
  level <- 0; sentence <- 1; attempt <- 1; rows <- list()
  while (sentence <= sentences) {
    correct <- rbinom(1, keywords, plogis(4 * slope * (level - l50)))
    all_right <- correct == keywords
    repeat_first <- sentence == 1 && !all_right && attempt <= 10
    wanted <- if (repeat_first) 4 else (if (sentence <= 4) 4 else 2) * (if (all_right) -1 else 1)
    next_level <- min(max(level + wanted, -30), 30)
    rows[[length(rows) + 1]] <- data.frame(presentation = length(rows) + 1, sentence_index = sentence,
                                           attempt = attempt, level_db = level, keywords = keywords,
                                           correct = correct, next_level_db = next_level)
    level <- next_level
    if (repeat_first) attempt <- attempt + 1 else { sentence <- sentence + 1; attempt <- 1 }
  }
  do.call(rbind, rows)
}

conditions <- c("audio-only", "av-a", "av-b")
trials <- list()
for (s in 1:20) {
  ao <- rnorm(1, -3, 1.5)
  l50 <- c(ao, ao - 3 + rnorm(1, 0, 0.5), ao - 5 + rnorm(1, 0, 4))
  for (j in 1:3) {
    t <- track(l50[j])
    trials[[length(trials) + 1]] <- cbind(data.frame(subject = sprintf("s%02d", s), phase = "test",
                                                     condition = conditions[j]), t)
  }
}
trials <- do.call(rbind, trials)
write.csv(trials, file.path(dir, paste0(case, ".adaptive_trials.csv")), row.names = FALSE, quote = FALSE)

# SRT per track: last presentation of each sentence from sentence 5 on, plus the next level.
srt_of <- function(t) {
  last <- t[!duplicated(t$sentence_index, fromLast = TRUE) & t$sentence_index >= 5, ]
  mean(c(last$level_db, t$next_level_db[nrow(t)]))
}
srt <- do.call(rbind, lapply(split(trials, list(trials$subject, trials$condition), drop = TRUE), function(t)
  data.frame(subject = t$subject[1], condition = t$condition[1], srt = srt_of(t))))
srt$subject <- factor(srt$subject)
srt$condition <- factor(srt$condition, levels = conditions)
srt <- srt[order(srt$subject, srt$condition), ]

fit <- aov(srt ~ condition + Error(subject / condition), data = srt)
within <- summary(fit)[["Error: subject:condition"]][[1]]
a <- suppressMessages(aov_ez("subject", "srt", srt, within = "condition",
                             anova_table = list(correction = "none", es = c("pes", "ges"))))
sa <- summary(a)
out <- list(case = case, n = nlevels(srt$subject), k = length(conditions),
            srt = lapply(seq_len(nrow(srt)), function(i)
              list(subject = as.character(srt$subject[i]), condition = as.character(srt$condition[i]),
                   srt_db = srt$srt[i])),
            F = within["condition", "F value"], p = within["condition", "Pr(>F)"],
            df_conditions = within["condition", "Df"], df_error = within["Residuals", "Df"],
            afex_F = a$anova_table$F, afex_p = a$anova_table$`Pr(>F)`, pes = a$anova_table$pes,
            mauchly_W = sa$sphericity.tests[1, "Test statistic"], mauchly_p = sa$sphericity.tests[1, "p-value"],
            gg_epsilon = sa$pval.adjustments[1, "GG eps"], gg_p = sa$pval.adjustments[1, "Pr(>F[GG])"],
            hf_epsilon = sa$pval.adjustments[1, "HF eps"], hf_p = sa$pval.adjustments[1, "Pr(>F[HF])"])
Y <- sapply(conditions, function(cn) srt$srt[srt$condition == cn])
benefits <- list(); p <- c()
for (j in 2:3) {
  tt <- t.test(Y[, 1], Y[, j], paired = TRUE)
  benefits[[length(benefits) + 1]] <- list(condition = conditions[j], benefit_db = mean(Y[, 1] - Y[, j]),
                                           t = unname(tt$statistic), df = unname(tt$parameter), p = tt$p.value,
                                           ci_low_db = tt$conf.int[1], ci_high_db = tt$conf.int[2])
  p <- c(p, tt$p.value)
}
holm <- p.adjust(p, "holm")
for (j in seq_along(benefits)) benefits[[j]]$p_holm <- holm[j]
out$benefits <- benefits
out$generated_by <- paste(R.version.string, "; afex", packageVersion("afex"), "; car", packageVersion("car"))
writeLines(toJSON(out, auto_unbox = TRUE, digits = I(17), na = "null", pretty = TRUE),
           file.path(dir, paste0(case, ".expected.json")))
cat(case, ": F =", out$F, " p =", out$p, " W =", out$mauchly_W, " p(W) =", out$mauchly_p, " GG =", out$gg_epsilon,
    " HF =", out$hf_epsilon, " benefit p =", p, " Holm =", holm, "\n")
