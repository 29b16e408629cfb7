// The "Presentation timing" section of the report (timing_report.h).
#include "avsi/analysis/timing_report.h"

#include <algorithm>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"
#include "report_html.h"

namespace avsi::analysis {

namespace fs = std::filesystem;

std::vector<TimingCertificateRow> read_timing_certificates(const fs::path& path) {
    const CsvTable table = read_csv(path);
    DiagnosticList problems;
    auto col = [&](const char* name) { return table.require_column(name); };
    const std::size_t subject = col("subject"), verdict = col("verdict"), trials = col("trials"),
                      frames_total = col("frames_total"), dropped = col("dropped_frames"),
                      dropped_share = col("dropped_share"), offset_frames = col("offset_frames"),
                      p5 = col("offset_p5_ms"), median = col("offset_median_ms"), p95 = col("offset_p95_ms"),
                      lo = col("offset_min_ms"), hi = col("offset_max_ms"), outside = col("outside_share"),
                      refresh = col("refresh_hz"), latency = col("output_latency_ms"),
                      lead = col("tolerance_audio_lead_ms"), lag = col("tolerance_audio_lag_ms"),
                      outside_tol = col("tolerance_outside_share"), dropped_tol = col("tolerance_dropped_share"),
                      reasons = col("reasons");
    std::vector<TimingCertificateRow> out;
    for (const auto& row : table.rows) {
        auto number = [&](std::size_t c) {
            const auto v = parse_double(row.fields[c]);
            if (!v) problems.add(table.path, row.line, 1, table.header[c], fmt::format("expected a number, got \"{}\"", excerpt(row.fields[c])));
            return v.value_or(0.0);
        };
        TimingCertificateRow r;
        r.subject = row.fields[subject];
        r.verdict = row.fields[verdict];
        if (r.verdict != "pass" && r.verdict != "fail" && r.verdict != "unknown")
            problems.add(table.path, row.line, 1, "verdict",
                         fmt::format("expected pass, fail or unknown, got \"{}\"", excerpt(r.verdict)));
        r.trials = static_cast<int>(number(trials));
        r.frames_total = static_cast<int>(number(frames_total));
        r.dropped_frames = static_cast<int>(number(dropped));
        r.dropped_share = number(dropped_share);
        r.offset_frames = static_cast<int>(number(offset_frames));
        r.offset_p5_ms = number(p5);
        r.offset_median_ms = number(median);
        r.offset_p95_ms = number(p95);
        r.offset_min_ms = number(lo);
        r.offset_max_ms = number(hi);
        r.outside_share = number(outside);
        r.refresh_hz = number(refresh);
        if (!row.fields[latency].empty()) r.output_latency_ms = number(latency);
        r.tolerance_audio_lead_ms = number(lead);
        r.tolerance_audio_lag_ms = number(lag);
        r.tolerance_outside_share = number(outside_tol);
        r.tolerance_dropped_share = number(dropped_tol);
        r.reasons = row.fields[reasons];
        out.push_back(std::move(r));
    }
    problems.throw_if_any();
    return out;
}

Scores exclude_timing_failures(const Scores& scores, const std::vector<TimingCertificateRow>& rows,
                               std::vector<std::string>& excluded) {
    std::set<std::string> failing;
    for (const auto& r : rows)
        if (r.verdict == "fail") failing.insert(r.subject);
    Scores out = scores;
    out.cells.clear();
    std::set<std::string> dropped;
    for (const auto& c : scores.cells) {
        if (failing.count(c.subject)) {
            dropped.insert(c.subject);
            continue;
        }
        out.cells.push_back(c);
    }
    excluded.assign(dropped.begin(), dropped.end());
    return out;
}

namespace {

// The section's cells per subject, shared by the Markdown and HTML tables.
std::vector<std::string> cells(const TimingCertificateRow& r) {
    return {r.subject,
            r.verdict,
            std::to_string(r.trials),
            fmt::format("{:.1f}", r.offset_median_ms),
            fmt::format("{:.1f} … {:.1f}", r.offset_p5_ms, r.offset_p95_ms),
            fmt::format("{:.1f} … {:.1f}", r.offset_min_ms, r.offset_max_ms),
            fmt::format("{:.1f}", 100.0 * r.outside_share),
            fmt::format("{} of {} ({:.1f} %)", r.dropped_frames, r.frames_total, 100.0 * r.dropped_share),
            fmt::format("{:.2f}", r.refresh_hz),
            r.output_latency_ms ? fmt::format("{:.1f}", *r.output_latency_ms) : "not reported",
            r.reasons};
}

const std::vector<std::string> k_columns = {"Subject", "Verdict", "Trials", "A/V offset median (ms)",
                                            "5–95 % (ms)", "range (ms)", "frames outside (%)", "dropped frames",
                                            "refresh (Hz)", "outputLatency (ms)", "why"};

std::string tolerance_text(const std::vector<TimingCertificateRow>& rows) {
    const TimingCertificateRow& t = rows.front();
    return fmt::format(
        "Tolerances: the A/V offset of each frame within [−{:g}, +{:g}] ms (ITU-R BT.1359-1 detectability: sound "
        "behind the picture by more than {:g} ms or ahead of it by more than {:g} ms; positive offsets mean the sound "
        "is ahead) for all but {:g} % of frames, and at most {:g} % of frames dropped. The offsets are the browser's "
        "own estimate (requestVideoFrameCallback display times, the media clock and the AudioContext's reported "
        "output latency), not a measurement at the screen and the ear: a device that misreports its latency (e.g. "
        "Bluetooth headphones) is not seen.",
        t.tolerance_audio_lag_ms, t.tolerance_audio_lead_ms, t.tolerance_audio_lag_ms, t.tolerance_audio_lead_ms,
        100.0 * t.tolerance_outside_share, 100.0 * t.tolerance_dropped_share);
}

}  // namespace

void append_timing_section(const fs::path& out_dir, const std::vector<TimingCertificateRow>& rows,
                           const std::vector<std::string>& excluded, const fs::path& source) {
    const std::string excluded_text =
        excluded.empty() ? "No subject was excluded for timing."
                         : fmt::format("Excluded from the analysis for failing the timing tolerances "
                                       "(--exclude-timing-fail): subject{} {}.",
                                       excluded.size() == 1 ? "" : "s", fmt::format("{}", fmt::join(excluded, ", ")));
    // Markdown.
    std::string md = "\n## Presentation timing (online)\n\n";
    md += fmt::format("Per participant, from `{}`. ", source.filename().string());
    md += rows.empty() ? "The file lists no participant.\n" : tolerance_text(rows) + "\n\n";
    if (!rows.empty()) {
        md += "| " + fmt::format("{}", fmt::join(k_columns, " | ")) + " |\n|";
        for (std::size_t i = 0; i < k_columns.size(); ++i) md += i < 2 || i + 1 == k_columns.size() ? "---|" : "---:|";
        md += "\n";
        for (const auto& r : rows) {
            auto c = cells(r);
            for (auto& s : c) std::replace(s.begin(), s.end(), '|', '/');
            md += "| " + fmt::format("{}", fmt::join(c, " | ")) + " |\n";
        }
        md += "\n";
    }
    md += excluded_text + "\n";
    const fs::path md_path = out_dir / "report.md";
    write_text_file(md_path, read_text_file(md_path) + md);

    // HTML: the same before </body>.
    std::string h = "<h2>Presentation timing (online)</h2>\n<p>" +
                    xml_escape(fmt::format("Per participant, from {}. ", source.filename().string()) +
                                (rows.empty() ? "The file lists no participant." : tolerance_text(rows))) +
                    "</p>\n";
    if (!rows.empty()) {
        h += "<table>\n<tr>";
        for (const auto& c : k_columns) h += "<th>" + xml_escape(c) + "</th>";
        h += "</tr>\n";
        for (const auto& r : rows) {
            h += "<tr>";
            for (const auto& c : cells(r)) h += "<td>" + xml_escape(c) + "</td>";
            h += "</tr>\n";
        }
        h += "</table>\n";
    }
    h += "<p>" + xml_escape(excluded_text) + "</p>\n";
    detail::append_to_report(out_dir, "", h);
}

}  // namespace avsi::analysis
