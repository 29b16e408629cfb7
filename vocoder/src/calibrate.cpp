// Grid search of band count × envelope cutoff for a target (E)STOI; see calibrate.h.
#include "avsi/vocoder/calibrate.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/vocoder/stoi.h"

namespace avsi::vocoder {

CalibrationResult calibrate(const std::vector<Audio>& corpus, const CalibrationSettings& s) {
    DiagnosticList problems;
    if (corpus.empty()) problems.add("", 0, 0, "corpus", "expected at least one recording, got none");
    if (!(s.target >= 0.0 && s.target <= 1.0))
        problems.add("", 0, 0, "target", fmt::format("expected a value in [0, 1], got {}", s.target));
    if (s.min_bands < 1 || s.max_bands > 64 || s.min_bands > s.max_bands)
        problems.add("", 0, 0, "bands", fmt::format("expected 1 <= min <= max <= 64, got {}..{}", s.min_bands, s.max_bands));
    if (s.cutoffs_hz.empty()) problems.add("", 0, 0, "cutoffs_hz", "expected at least one envelope cutoff, got none");
    problems.throw_if_any();
    // Every cell must be valid for every recording's rate before any work starts.
    for (const Audio& audio : corpus)
        for (double cutoff : s.cutoffs_hz) {
            VocoderSettings v = s.base;
            v.bands = s.max_bands;
            v.envelope_cutoff_hz = cutoff;
            validate_settings(v, audio.sample_rate_hz, "calibration");
        }

    struct Job {
        int bands;
        double cutoff_hz;
    };
    std::vector<Job> jobs;
    for (int b = s.min_bands; b <= s.max_bands; ++b)
        for (double c : s.cutoffs_hz) jobs.push_back({b, c});
    std::vector<CalibrationCell> cells(jobs.size());
    std::vector<std::string> errors;
    std::mutex error_mutex;
    std::atomic<std::size_t> next{0};
    Progress progress("calibrate", jobs.size());
    auto worker = [&] {
        for (std::size_t i = next++; i < jobs.size(); i = next++) {
            try {
                VocoderSettings v = s.base;
                v.bands = jobs[i].bands;
                v.envelope_cutoff_hz = jobs[i].cutoff_hz;
                std::vector<double> scores;
                for (const Audio& audio : corpus)
                    scores.push_back(stoi(audio, vocode(audio, v).audio, {.extended = s.extended}));
                double mean = 0.0, var = 0.0;
                for (double d : scores) mean += d;
                mean /= static_cast<double>(scores.size());
                for (double d : scores) var += (d - mean) * (d - mean);
                const double sd = scores.size() > 1 ? std::sqrt(var / static_cast<double>(scores.size() - 1)) : 0.0;
                cells[i] = {jobs[i].bands, jobs[i].cutoff_hz, mean, sd};
            } catch (const std::exception& e) {
                std::lock_guard lock(error_mutex);
                errors.push_back(e.what());
            }
            progress.advance();
        }
    };
    unsigned threads = s.threads ? s.threads : std::max(1u, std::thread::hardware_concurrency());
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
    progress.finish();
    if (!errors.empty()) throw InputError(Diagnostic{"", 0, 0, "calibration", errors.front()});

    CalibrationResult result;
    result.table = cells;
    result.files = corpus.size();
    result.extended = s.extended;
    result.target = s.target;
    result.best = cells.front();
    for (const auto& c : cells)
        if (std::abs(c.mean - s.target) < std::abs(result.best.mean - s.target)) result.best = c;
    log_info("calibration: {} bands, envelope cutoff {} Hz gives mean {} {:.3f} (target {:.3f})", result.best.bands,
             result.best.cutoff_hz, s.extended ? "ESTOI" : "STOI", result.best.mean, s.target);
    return result;
}

std::string CalibrationResult::text() const {
    std::vector<double> cutoffs;
    for (const auto& c : table)
        if (std::find(cutoffs.begin(), cutoffs.end(), c.cutoff_hz) == cutoffs.end()) cutoffs.push_back(c.cutoff_hz);
    std::string out = fmt::format("mean {} (sd) over {} file(s), by band count (rows) and envelope cutoff in Hz "
                                  "(columns); target {:.3f}, * = closest\n",
                                  extended ? "ESTOI" : "STOI", files, target);
    out += fmt::format("{:>6}", "bands");
    for (double c : cutoffs) out += fmt::format("{:>18}", fmt::format("{:g} Hz", c));
    out += "\n";
    int row = -1;
    for (const auto& c : table) {
        if (c.bands != row) {
            if (row != -1) out += "\n";
            row = c.bands;
            out += fmt::format("{:>6}", c.bands);
        }
        const bool is_best = c.bands == best.bands && c.cutoff_hz == best.cutoff_hz;
        out += fmt::format("{:>18}", fmt::format("{}{:.3f} ({:.3f})", is_best ? "*" : "", c.mean, c.sd));
    }
    out += "\n";
    out += fmt::format("closest: {} bands, envelope cutoff {:g} Hz, mean {:.3f}\n", best.bands, best.cutoff_hz, best.mean);
    return out;
}

}  // namespace avsi::vocoder
