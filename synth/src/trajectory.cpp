// Trajectory frame counts and CSV I/O (`time_s,<param>…`).
#include "avsi/synth/trajectory.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "avsi/core/checks.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::synth {

std::size_t frame_count(double duration_s, double fps) {
    AVSI_ASSERT(fps > 0.0);
    if (!(duration_s > 0.0)) return 0;
    return static_cast<std::size_t>(std::ceil(duration_s * fps - 1e-9));
}

bool RangeReport::any() const {
    for (std::size_t n : frames_outside)
        if (n > 0) return true;
    return false;
}

RangeReport check_ranges(Trajectory& trajectory, bool clamp) {
    RangeReport report;
    for (std::size_t k = 0; k < trajectory.frames.size(); ++k)
        for (const auto& info : params()) {
            double& v = trajectory.frames[k][index(info.param)];
            const std::size_t p = index(info.param);
            if (!std::isfinite(v) || (v >= info.min && v <= info.max)) continue;
            const double excess = v < info.min ? info.min - v : v - info.max;
            const double worst = report.worst[p] < info.min ? info.min - report.worst[p] : report.worst[p] - info.max;
            if (report.frames_outside[p] == 0 || excess > worst) {
                report.worst[p] = v;
                report.worst_frame[p] = k;
            }
            ++report.frames_outside[p];
            if (clamp) v = std::clamp(v, info.min, info.max);
        }
    return report;
}

Trajectory read_trajectory_csv(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::string file = path.string();
    const std::size_t time_col = table.require_column("time_s");
    std::array<std::size_t, param_count> cols{};
    for (const auto& info : params()) cols[index(info.param)] = table.require_column(info.name);

    DiagnosticList problems;
    std::vector<double> times;
    Trajectory out;
    for (const auto& row : table.rows) {
        if (row.fields.size() != table.header.size()) {
            problems.add(file, row.line, 0, "",
                         fmt::format("expected {} fields, got {}", table.header.size(), row.fields.size()));
            continue;
        }
        const auto t = parse_double(row.fields[time_col]);
        if (!t) {
            problems.add(file, row.line, static_cast<int>(time_col) + 1, "time_s",
                         fmt::format("expected a number, got \"{}\"", row.fields[time_col]));
            continue;
        }
        require_time_s(*t, at(file, row.line, static_cast<int>(time_col) + 1, "time_s"));
        Frame frame{};
        for (const auto& info : params()) {
            const std::size_t c = cols[index(info.param)];
            const auto v = parse_double(row.fields[c]);
            if (!v) {
                problems.add(file, row.line, static_cast<int>(c) + 1, std::string(info.name),
                             fmt::format("expected a number, got \"{}\"", row.fields[c]));
                continue;
            }
            // Within one range width beyond the documented range.
            frame[index(info.param)] = require_near_range(
                *v, info.min, info.max, 1.0, at(file, row.line, static_cast<int>(c) + 1, std::string(info.name)));
        }
        times.push_back(*t);
        out.frames.push_back(frame);
    }
    problems.throw_if_any();
    if (times.size() < 2)
        throw InputError(path, fmt::format("expected at least 2 frames to know the frame rate, got {}",
                                           times.size()));
    if (std::abs(times[0]) > 1e-6)
        throw InputError(file, table.rows[0].line, 0, "time_s",
                         fmt::format("expected the first frame at 0 s, got {}", times[0]));
    if (!(times[1] > times[0]))
        throw InputError(file, table.rows[1].line, 0, "time_s", "expected increasing times");
    // Each step as the first one, up to the rounding of the written decimals:
    // the error names the row where the step changes.
    const double first_step_s = times[1] - times[0];
    for (std::size_t k = 2; k < times.size(); ++k) {
        const double step_s = times[k] - times[k - 1];
        if (std::abs(step_s - first_step_s) > 2e-6 + 1e-3 * first_step_s)
            throw InputError(file, table.rows[k].line, 0, "time_s",
                             fmt::format("expected a constant frame step of {} s (frame {} at {} s), got {}",
                                         first_step_s, k, times[k - 1] + first_step_s, times[k]));
    }
    // The rate from the whole span (a step rounded to the written decimals,
    // 0.016667 for 60 fps, would drift a frame off in a few hundred frames),
    // snapped to a whole number of frames per second when that close.
    double fps = static_cast<double>(times.size() - 1) / (times.back() - times.front());
    if (!(fps > 0.0) || !std::isfinite(fps))
        throw InputError(file, table.rows.back().line, 0, "time_s", "expected increasing times");
    if (std::abs(fps - std::round(fps)) < 1e-4 * fps) fps = std::round(fps);
    // A constant step: every time within 1 µs of k / fps.
    for (std::size_t k = 0; k < times.size(); ++k) {
        const double expected = static_cast<double>(k) / fps;
        if (std::abs(times[k] - expected) > 1e-6)
            throw InputError(file, table.rows[k].line, 0, "time_s",
                             fmt::format("expected a constant frame step of {} s (frame {} at {} s), got {}",
                                         1.0 / fps, k, expected, times[k]));
    }
    out.fps = fps;
    return out;
}

void write_trajectory_csv(const std::filesystem::path& path, const Trajectory& trajectory) {
    std::string text = "time_s";
    for (const auto& info : params()) {
        text += ',';
        text += info.name;
    }
    text += '\n';
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        text += fmt::format("{}", trajectory.time_s(k));
        for (double v : trajectory.frames[k]) text += fmt::format(",{}", v);
        text += '\n';
    }
    write_text_file(path, text);
}

}  // namespace avsi::synth
