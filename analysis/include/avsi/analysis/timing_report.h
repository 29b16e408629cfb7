// The online participants' timing certificates in the report: reads
// timing_certificate.csv (written by `avsi export` for online sessions; see
// experiment's timing_certificate.h), optionally leaves out the subjects
// whose presentation timing failed the tolerances, and adds a "Presentation
// timing" section to report.md and index.html.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/scores.h"

namespace avsi::analysis {

// One row of timing_certificate.csv.
struct TimingCertificateRow {
    std::string subject;
    std::string verdict;  // pass, fail, unknown
    int trials = 0;
    int frames_total = 0;
    int dropped_frames = 0;
    double dropped_share = 0.0;
    int offset_frames = 0;
    double offset_p5_ms = 0.0, offset_median_ms = 0.0, offset_p95_ms = 0.0, offset_min_ms = 0.0, offset_max_ms = 0.0;
    double outside_share = 0.0;
    double refresh_hz = 0.0;
    std::optional<double> output_latency_ms;
    double tolerance_audio_lead_ms = 0.0, tolerance_audio_lag_ms = 0.0;
    double tolerance_outside_share = 0.0, tolerance_dropped_share = 0.0;
    std::string reasons;
};

// Reads timing_certificate.csv; throws InputError (file:line) on a missing
// column, a bad number or an unknown verdict.
std::vector<TimingCertificateRow> read_timing_certificates(const std::filesystem::path& path);

// The scores without the subjects whose verdict is "fail"; `excluded` gets their ids.
Scores exclude_timing_failures(const Scores& scores, const std::vector<TimingCertificateRow>& rows,
                               std::vector<std::string>& excluded);

// Appends the "Presentation timing" section (one row per subject, the
// tolerances, what the numbers cannot tell, who was excluded) to the
// report.md and index.html in `out_dir`.
void append_timing_section(const std::filesystem::path& out_dir, const std::vector<TimingCertificateRow>& rows,
                           const std::vector<std::string>& excluded, const std::filesystem::path& source);

}  // namespace avsi::analysis
