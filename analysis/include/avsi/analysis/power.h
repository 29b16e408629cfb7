// Power by simulation (`avsi power`), a planning aid: for given condition
// means and a design like the reference study's, simulate keyword-level data
// with subject, sentence and subject × condition random effects on the logit
// scale,
//   logit P(correct) = logit(mean_c) + u_subject + v_sentence + w_subject,condition,
//   u ~ N(0, subject_sd²), v ~ N(0, sentence_sd²), w ~ N(0, condition_sd²);
// w is the random slope: how much a listener's benefit from a condition
// differs from the mean benefit (MacLeod & Summerfield 1987: the audiovisual
// benefit ranged 6-15 dB across listeners). Its default, kConditionSdDefault,
// is derived from that range (kConditionSdSource says how; every output
// states it); condition_sd = 0 gives the model without it, number for number.
// with sentences in k lists of `sentences_per_cell`, list l shown to subject i
// in condition (l + i) mod k (Latin-square rotation), `keywords_per_sentence`
// Bernoulli keywords per sentence. Each simulated experiment is scored to
// subject × condition percent correct and analysed like real data: the
// repeated-measures ANOVA (uncorrected and Greenhouse-Geisser) and the paired
// LSD test of one contrast. Power = share of experiments with p < alpha.
// Every output says it is a simulation.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/shards.h"

namespace avsi::analysis {

// The default subject × condition SD (logit): MacLeod & Summerfield's 6-15 dB
// range of the audiovisual benefit read as ±2 SD (SD 2.25 dB), times the
// logit slope of a 0.15/dB psychometric function at its midpoint
// (4 × 0.15 = 0.6 logit/dB), is an SD of 1.35 logit for a difference of two
// conditions, i.e. 1.35/√2 = 0.95 per condition.
inline constexpr double kConditionSdDefault = 0.95;
inline constexpr const char* kConditionSdSource =
    "MacLeod & Summerfield (1987): audiovisual benefit 6-15 dB across listeners, read as +/-2 SD = 2.25 dB, "
    "x 0.6 logit/dB (slope 0.15/dB at 50 %) = 1.35 logit for a difference of two conditions, /sqrt(2) per condition";

struct PowerSettings {
    std::vector<double> means_percent;          // one per condition, in (0, 100)
    std::vector<std::size_t> subject_counts = {10, 15, 20, 25, 30, 35, 40};
    std::size_t sentences_per_cell = 15;
    std::size_t keywords_per_sentence = 3;
    double subject_sd = 0.5;   // logit scale
    double sentence_sd = 0.5;  // logit scale
    double condition_sd = kConditionSdDefault;  // subject × condition random slope, logit scale
    std::size_t simulations = 1000;
    std::uint64_t seed = 1;
    std::size_t contrast_a = 0, contrast_b = 0;  // 0-based; a == b: last minus first
    double alpha = 0.05;
    std::size_t threads = 0;  // 0: all cores
};

struct PowerPoint {
    std::size_t subjects = 0;
    std::size_t simulations = 0;
    double power_anova = 0.0;     // uncorrected F test
    double power_anova_gg = 0.0;  // Greenhouse-Geisser corrected
    double power_contrast = 0.0;  // paired LSD t-test of the contrast
    double mc_se_anova = 0.0;     // Monte Carlo standard error sqrt(p(1-p)/sims)
    double mc_se_contrast = 0.0;
    double mean_percent = 0.0;    // average simulated percent correct (a sanity check)
};

struct PowerResult {
    PowerSettings settings;
    std::string contrast;  // e.g. "c6 - c1"
    std::vector<PowerPoint> points;
};

// Validates the settings (InputError naming the option) and runs the
// simulation in parallel. Results depend only on the settings and the seed,
// not on the number of threads.
PowerResult simulate_power(const PowerSettings& settings);

// A cluster run (docs/cluster.md): shard K of N simulates, for every
// subject count, its contiguous share of the experiments (shard_range), each
// from the seed it has in the whole run, and writes their outcomes to
// <out_dir>/power.shard-K-of-N.csv. Validates as simulate_power.
void simulate_power_shard(const PowerSettings& settings, ShardSpec shard, const std::filesystem::path& out_dir);

// The merge: the shard files in `out_dir` summarised into the result
// simulate_power(settings) gives, number for number. Every shard of the
// split must be there, made by this avsi with these settings (the thread
// count aside), each holding its own experiments: InputError naming the one
// missing, stale, foreign, claiming another's experiments or cut short.
PowerResult merge_power_shards(const PowerSettings& settings, const std::filesystem::path& out_dir);

// "10..40" (step 5), "10..40:2" or "10,20,30". Throws InputError naming --subjects.
std::vector<std::size_t> parse_subject_counts(const std::string& text);
// "60,70,75": percent means. Throws InputError naming --means.
std::vector<double> parse_means(const std::string& text);
// "2-1" or "c2-c1": 0-based (a, b) for k conditions. Throws InputError naming --contrast.
std::pair<std::size_t, std::size_t> parse_contrast(const std::string& text, std::size_t k);

// A plain-text table headed "Power by simulation".
std::string power_table(const PowerResult& result);
// power.csv (method column "simulation") and power.json.
void write_power_files(const std::filesystem::path& out_dir, const PowerResult& result);

}  // namespace avsi::analysis
