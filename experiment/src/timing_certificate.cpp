// Timing certificates per online participant (timing_certificate.h): the
// stored per-frame offsets and per-trial counts summarised per subject and
// judged against the tolerances.
#include "avsi/experiment/timing_certificate.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "avsi/core/csv.h"

namespace avsi::experiment {

namespace {

// The q-quantile of sorted values, linear between order statistics (R's type 7).
double quantile(const std::vector<double>& sorted, double q) {
    if (sorted.empty()) return 0.0;
    const double h = (double(sorted.size()) - 1.0) * q;
    const auto lo = static_cast<std::size_t>(std::floor(h));
    const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
    return sorted[lo] + (h - double(lo)) * (sorted[hi] - sorted[lo]);
}

std::optional<double> median_of(std::vector<double> values) {
    if (values.empty()) return std::nullopt;
    std::sort(values.begin(), values.end());
    return quantile(values, 0.5);
}

// The verdict and its reasons from the counts.
void judge(TimingCertificate& c, const TimingTolerance& tolerance) {
    if (c.offset_frames == 0) {
        c.verdict = TimingVerdict::Unknown;
        c.reasons.push_back("no per-frame timing (the browser lacks requestVideoFrameCallback)");
        return;
    }
    c.verdict = TimingVerdict::Pass;
    if (c.outside_share > tolerance.max_outside_share) {
        c.verdict = TimingVerdict::Fail;
        c.reasons.push_back(fmt::format("{:.1f} % of frames outside [-{:g}, +{:g}] ms (sound ahead on {}, behind on "
                                        "{}; at most {:g} % allowed)",
                                        100.0 * c.outside_share, tolerance.audio_lag_ms, tolerance.audio_lead_ms,
                                        c.audio_leading_frames, c.audio_lagging_frames,
                                        100.0 * tolerance.max_outside_share));
    }
    if (c.dropped_share > tolerance.max_dropped_share) {
        c.verdict = TimingVerdict::Fail;
        c.reasons.push_back(fmt::format("{:.1f} % of frames dropped ({} of {}; at most {:g} % allowed)",
                                        100.0 * c.dropped_share, c.dropped_frames, c.frames_total,
                                        100.0 * tolerance.max_dropped_share));
    }
}

}  // namespace

std::string to_string(TimingVerdict verdict) {
    switch (verdict) {
    case TimingVerdict::Pass: return "pass";
    case TimingVerdict::Fail: return "fail";
    case TimingVerdict::Unknown: return "unknown";
    }
    return "unknown";
}

std::vector<TimingCertificate> timing_certificates(const Store& store, const TimingTolerance& tolerance) {
    std::map<std::pair<int, int>, WebPresentation> web;
    for (const auto& w : store.web_timing()) web[{w.subject, w.position}] = w.web;
    struct Collected {
        TimingCertificate certificate;
        std::vector<double> offsets, refresh, output_latency, audio_path;
    };
    std::map<int, Collected> by_subject;
    for (const auto& t : store.timing(true)) {
        const auto it = web.find({t.subject, t.position});
        if (it == web.end()) continue;  // a lab presentation
        Collected& c = by_subject[t.subject];
        TimingCertificate& cert = c.certificate;
        const Presentation& p = t.presentation;
        cert.subject = t.subject;
        ++cert.trials;
        cert.frames_total += p.frames_total;
        cert.frames_shown += p.frames_shown;
        cert.dropped_frames += p.dropped_frames;
        cert.repeated_frames += p.repeated_frames;
        if (p.refresh_hz > 0) c.refresh.push_back(p.refresh_hz);
        if (it->second.output_latency_ms > 0) c.output_latency.push_back(it->second.output_latency_ms);
        if (it->second.audio_path_ms > 0) c.audio_path.push_back(it->second.audio_path_ms);
        for (const auto& f : p.flips) {
            c.offsets.push_back(f.offset_ms);
            if (f.offset_ms > tolerance.audio_lead_ms) ++cert.audio_leading_frames;
            if (f.offset_ms < -tolerance.audio_lag_ms) ++cert.audio_lagging_frames;
        }
    }
    std::vector<TimingCertificate> out;
    for (auto& [subject, c] : by_subject) {
        TimingCertificate& cert = c.certificate;
        std::sort(c.offsets.begin(), c.offsets.end());
        cert.offset_frames = static_cast<int>(c.offsets.size());
        if (!c.offsets.empty()) {
            cert.offset_min_ms = c.offsets.front();
            cert.offset_max_ms = c.offsets.back();
            cert.offset_p5_ms = quantile(c.offsets, 0.05);
            cert.offset_median_ms = quantile(c.offsets, 0.5);
            cert.offset_p95_ms = quantile(c.offsets, 0.95);
            double sum = 0.0;
            for (double v : c.offsets) sum += v;
            cert.offset_mean_ms = sum / double(c.offsets.size());
            cert.outside_share = double(cert.audio_leading_frames + cert.audio_lagging_frames) / double(c.offsets.size());
        }
        cert.dropped_share = cert.frames_total > 0 ? double(cert.dropped_frames) / double(cert.frames_total) : 0.0;
        cert.refresh_hz = median_of(c.refresh).value_or(0.0);
        cert.output_latency_ms = median_of(c.output_latency);
        cert.audio_path_ms = median_of(c.audio_path);
        judge(cert, tolerance);
        out.push_back(std::move(cert));
    }
    return out;
}

std::string timing_certificate_csv(const std::vector<TimingCertificate>& certificates, const TimingTolerance& tolerance) {
    auto ms = [](double v) { return fmt::format("{:.3f}", v); };
    auto share = [](double v) { return fmt::format("{:.4f}", v); };
    std::string csv = csv_line({"subject", "verdict", "trials", "frames_total", "frames_shown", "dropped_frames",
                                "dropped_share", "repeated_frames", "offset_frames", "offset_min_ms", "offset_p5_ms",
                                "offset_median_ms", "offset_mean_ms", "offset_p95_ms", "offset_max_ms",
                                "audio_leading_frames", "audio_lagging_frames", "outside_share", "refresh_hz",
                                "output_latency_ms", "audio_path_ms", "tolerance_audio_lead_ms",
                                "tolerance_audio_lag_ms", "tolerance_outside_share", "tolerance_dropped_share",
                                "reasons"});
    for (const auto& c : certificates) {
        std::string reasons;
        for (const auto& r : c.reasons) reasons += (reasons.empty() ? "" : "; ") + r;
        csv += csv_line({std::to_string(c.subject), to_string(c.verdict), std::to_string(c.trials),
                         std::to_string(c.frames_total), std::to_string(c.frames_shown), std::to_string(c.dropped_frames),
                         share(c.dropped_share), std::to_string(c.repeated_frames), std::to_string(c.offset_frames),
                         ms(c.offset_min_ms), ms(c.offset_p5_ms), ms(c.offset_median_ms), ms(c.offset_mean_ms),
                         ms(c.offset_p95_ms), ms(c.offset_max_ms), std::to_string(c.audio_leading_frames),
                         std::to_string(c.audio_lagging_frames), share(c.outside_share),
                         fmt::format("{:.3f}", c.refresh_hz), c.output_latency_ms ? ms(*c.output_latency_ms) : "",
                         c.audio_path_ms ? ms(*c.audio_path_ms) : "", fmt::format("{:g}", tolerance.audio_lead_ms),
                         fmt::format("{:g}", tolerance.audio_lag_ms), fmt::format("{:g}", tolerance.max_outside_share),
                         fmt::format("{:g}", tolerance.max_dropped_share), reasons});
    }
    return csv;
}

std::string describe(const TimingCertificate& c) {
    std::string out = fmt::format(
        "subject {}: timing {} — A/V offset over {} frames: median {:.1f} ms, 5–95 % {:.1f} … {:.1f} ms, range {:.1f} "
        "… {:.1f} ms (positive: sound ahead); {} of {} frames dropped ({:.1f} %), {} repeated; refresh {:.2f} Hz; "
        "outputLatency {}",
        c.subject, to_string(c.verdict), c.offset_frames, c.offset_median_ms, c.offset_p5_ms, c.offset_p95_ms,
        c.offset_min_ms, c.offset_max_ms, c.dropped_frames, c.frames_total, 100.0 * c.dropped_share, c.repeated_frames,
        c.refresh_hz, c.output_latency_ms ? fmt::format("{:.1f} ms", *c.output_latency_ms) : "not reported");
    for (const auto& r : c.reasons) out += "; " + r;
    return out;
}

}  // namespace avsi::experiment
