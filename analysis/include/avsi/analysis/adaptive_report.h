// `avsi analyze` on adaptive tracks: from the trials of adaptive SRT tracks
// (adaptive_trials.csv, written by `avsi export`) per subject and condition
// the SRT and its standard error, the visual benefit (reference SRT minus
// condition SRT, positive when the face helps) with a paired-t confidence
// interval, the repeated-measures ANOVA on the SRTs in dB (rm_anova.h, the
// same machinery as for percent correct), pairwise comparisons, one figure
// per subject with its tracks (level by presentation, reversals ringed), and
// a maximum-likelihood psychometric function per condition pooled across
// subjects. Each track is replayed under the protocol's [adaptive] rules
// and must give the stored levels, so a report never mixes rules.
//
//   adaptive_trials.csv: subject,condition,presentation,sentence_index,attempt,
//                        level_db,keywords,correct,next_level_db,... (extra columns ignored)
//
// Report folder: index.html, report.md, srt.csv, benefit.csv, anova.json,
// pairwise.csv, psychometric.csv, srt.png, psychometric.png, tracks/subject_<id>.png.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/adaptive.h"
#include "avsi/analysis/report.h"

namespace avsi::analysis {

// One presentation of a stored track.
struct AdaptiveTrialRow {
    std::string subject, condition;
    int presentation = 0;   // 1-based within the subject's track for the condition
    int sentence_index = 0; // 1-based sentence of the track
    int attempt = 1;
    double level_db = 0.0;
    int keywords = 0, correct = 0;
    double next_level_db = 0.0;
    int line = 0;           // in the file
    int level_column = 0;   // of level_db (1-based), for messages
};

// Reads adaptive_trials.csv (every field checked; problems with file:line).
std::vector<AdaptiveTrialRow> read_adaptive_trials(const std::filesystem::path& path);

// One subject × condition track, replayed.
struct TrackResult {
    std::string subject, condition;
    std::vector<TrackStep> steps;  // levels in the variable's units (dB, bands, Hz)
    SrtEstimate srt;  // the protocol's estimator, on the analysis scale (dB, or log2 of bands / Hz)
    SrtEstimate ml;   // the ML fit of the same track (for comparison), same scale
    TrackConvergence convergence;
    bool excluded = false;  // left out of the ANOVA and the benefit (not converged, not included)
};

// Reference minus condition, per subject.
struct VisualBenefit {
    std::string condition, reference;
    std::size_t n = 0;
    double mean_db = 0.0, sd_db = 0.0, se_db = 0.0;
    double ci_low_db = 0.0, ci_high_db = 0.0;
    std::optional<double> t, p_value;
    std::optional<double> p_holm;  // Holm-adjusted over the k − 1 benefits (R p.adjust "holm")
    double df = 0.0;
};

// The pooled psychometric function of one condition.
struct ConditionFit {
    std::string condition;
    PsychometricFit fit;
    std::vector<PsychometricPoint> points;  // pooled per level (rounded to 0.1 dB)
};

struct SrtAnalysis {
    TrackSettings settings;
    // The scale of thresholds and statistics: "dB" for SNR tracks; for list
    // variables "log2(bands)" or "log2(Hz)": levels of band counts and
    // cutoffs are roughly logarithmic, so thresholds are means of log2
    // levels (geometric means), the fits are in log2 units and the ANOVA and
    // benefit run on log2 thresholds.
    std::string scale = "dB";
    bool log2_scale = false;
    bool include_unconverged = false;
    int excluded_tracks = 0;              // tracks left out (not converged)
    std::vector<std::string> excluded;    // "subject s03, audio-only: at the upper bound from sentence 6"
    std::vector<std::string> warnings;    // design warnings (ceilings below the tracked target)
    std::string masker;                   // masker_description of the protocol ("" without noise)
    // The variable's units: "dB" (SNR), or "bands" / "Hz" for a list variable
    // (whose track steps, levels and thresholds are then in those units).
    std::string unit = "dB";
    std::string level_label = "SNR (dB)";     // axis label of a level
    std::string threshold_label = "dB SNR";   // unit of a threshold in headings
    std::string reference;
    std::vector<TrackResult> tracks;
    std::vector<std::string> conditions;  // report order
    Scores srts;                          // subject × condition SRT in the `percent` field (dB)
    std::optional<AnalysisResult> anova;  // nullopt with fewer than 2 complete subjects
    std::vector<VisualBenefit> benefits;
    std::vector<ConditionFit> fits;
    std::vector<std::string> notes;
};

// Replays and estimates every track, then the statistics. `conditions`
// orders the report (empty: first appearance); `reference` is the audio-only
// condition (empty: the first). Throws InputError naming `source` and the
// line when a stored level is not what the rules give.
// With `protocol` (its [adaptive] section) whose variable is "bands" or
// "cutoff", the stored levels are the list's values, the track is replayed on
// positions, levels are reported in the variable's units and thresholds,
// fits and statistics on its log2 scale (SrtAnalysis::scale).
// Tracks that did not converge (track_convergence) are flagged; unless
// `include_unconverged`, their SRTs are left out of the ANOVA (the subject is
// then dropped listwise) and of the benefit, and the report names them.
// `protocol` also gives the conditions' ceilings (pooled fits use them).
SrtAnalysis analyze_srt(const std::vector<AdaptiveTrialRow>& rows, const TrackSettings& settings,
                        const std::vector<std::string>& conditions, const std::string& reference,
                        const std::string& source, double confidence = 0.95,
                        const AdaptiveProtocol* protocol = nullptr, bool include_unconverged = false);

struct SrtReportSettings {
    std::filesystem::path out_dir;
    std::filesystem::path source;
    std::filesystem::path protocol;
    std::string title = "Speech reception thresholds by condition";
    double confidence = 0.95;
};

// Writes the report folder listed above.
void write_srt_report(const SrtAnalysis& analysis, const SrtReportSettings& settings);

struct AdaptiveAnalyzeSettings {
    std::filesystem::path input;     // adaptive_trials.csv
    std::filesystem::path protocol;  // its [adaptive] rules, conditions and reference
    std::filesystem::path out_dir;
    double confidence = 0.95;
    std::string title = "Speech reception thresholds by condition";
    bool include_unconverged = false;  // --include-unconverged
};

// `avsi analyze --adaptive`: reads, replays, analyses and writes the report.
SrtAnalysis analyze_adaptive_file(const AdaptiveAnalyzeSettings& settings);

// True when a CSV file's header has the adaptive trial columns (level_db and presentation).
bool is_adaptive_trials_file(const std::filesystem::path& path);

}  // namespace avsi::analysis
