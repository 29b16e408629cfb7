// The closure constraint (closure_constraint.h): the least change of a
// model's frame that brings its lips to closure or labiodental contact.
#include "avsi/synth/closure_constraint.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "avsi/core/error.h"
#include "avsi/synth/articulation_check.h"

namespace avsi::synth {

namespace {

// The fall-off stops at this many σ.
constexpr double reach_sigmas = 4.0;

// One constrained segment: its frames and each frame's correction.
struct Segment {
    bool bilabial = true;
    std::vector<std::size_t> frames;  // ascending
    std::vector<Frame> deltas;        // per frame, zero outside the task's parameters
    bool unmet = false;
};

// The frames of [start, end), or the one nearest the segment's centre.
std::vector<std::size_t> segment_frames(const Phone& phone, std::span<const double> times_s) {
    std::vector<std::size_t> out;
    for (std::size_t k = 0; k < times_s.size(); ++k)
        if (times_s[k] >= phone.start_s && times_s[k] < phone.end_s) out.push_back(k);
    if (!out.empty() || times_s.empty()) return out;
    const double centre = phone.centre_s();
    std::size_t nearest = 0;
    for (std::size_t k = 1; k < times_s.size(); ++k)
        if (std::fabs(times_s[k] - centre) < std::fabs(times_s[nearest] - centre)) nearest = k;
    return {nearest};
}

// The task's value at `frame`.
double task_value(const LipTaskFunction& tasks, const Frame& frame, bool bilabial) {
    const LipTaskMeasures m = tasks(frame);
    return bilabial ? m.aperture_mm : m.lip_to_incisors_mm;
}

// Moves `frame` the least way (in units of each parameter's range) until its
// task is at most `goal`; returns whether it got there.
bool solve_frame(Frame& frame, bool bilabial, double goal, const LipTaskFunction& tasks, int max_steps) {
    const auto& moved = bilabial ? bilabial_task_params() : labiodental_task_params();
    // Aim a little past the goal so that curvature does not leave the
    // iteration creeping toward it from above.
    const double aim = goal - 0.05;
    for (int step = 0; step < max_steps; ++step) {
        const double value = task_value(tasks, frame, bilabial);
        if (value <= goal) return true;
        std::array<double, param_count> gradient{};
        double denominator = 0.0;
        for (Param p : moved) {
            const ParamInfo& info = param_info(p);
            const std::size_t i = index(p);
            double h = 1e-3 * info.range();
            if (frame[i] + h > info.max) h = -h;
            Frame probe = frame;
            probe[i] += h;
            gradient[i] = (task_value(tasks, probe, bilabial) - value) / h;
            denominator += info.range() * info.range() * gradient[i] * gradient[i];
        }
        if (!(denominator > 1e-12)) return false;  // the task does not move with these parameters here
        for (Param p : moved) {
            const ParamInfo& info = param_info(p);
            const std::size_t i = index(p);
            const double change = -(value - aim) * info.range() * info.range() * gradient[i] / denominator;
            frame[i] = std::clamp(frame[i] + change, info.min, info.max);
        }
    }
    return task_value(tasks, frame, bilabial) <= goal;
}

}  // namespace

const std::vector<Param>& bilabial_task_params() {
    static const std::vector<Param> p{Param::JawRotation, Param::UpperLipRaise, Param::LowerLipDepression};
    return p;
}

const std::vector<Param>& labiodental_task_params() {
    static const std::vector<Param> p{Param::JawRotation, Param::LowerLipRetraction, Param::LowerLipDepression};
    return p;
}

void ClosureStats::add(const ClosureStats& other) {
    frames += other.frames;
    frames_changed += other.frames_changed;
    segments += other.segments;
    segments_changed += other.segments_changed;
    segments_unmet += other.segments_unmet;
    for (std::size_t p = 0; p < param_count; ++p) sum_abs_change[p] += other.sum_abs_change[p];
}

double ClosureStats::mean_abs_change(Param p) const {
    return frames_changed ? sum_abs_change[index(p)] / static_cast<double>(frames_changed) : 0.0;
}

ClosureStats constrain_closure(const PhoneSequence& phones, std::span<const double> times_s,
                               const LipTaskFunction& tasks, const ClosureSettings& settings,
                               std::vector<Frame>& frames) {
    AVSI_ASSERT(frames.size() == times_s.size());
    AVSI_ASSERT(settings.transition_s > 0.0 && settings.max_steps > 0);
    AVSI_ASSERT(tasks);
    ClosureStats stats;
    stats.frames = frames.size();
    if (frames.empty()) return stats;
    const std::vector<Frame> model = frames;

    // 1. Each segment's frames, moved to their goal (a frame shared by two
    //    segments meets both: the second starts from the first's result).
    std::vector<Segment> segments;
    std::vector<bool> constrained(frames.size(), false);
    for (const Phone& phone : phones) {
        const bool bilabial = is_bilabial(phone.symbol);
        if (!bilabial && !is_labiodental(phone.symbol)) continue;
        Segment s;
        s.bilabial = bilabial;
        s.frames = segment_frames(phone, times_s);
        const double goal = bilabial ? settings.aperture_goal_mm : settings.contact_goal_mm;
        for (std::size_t k : s.frames) {
            if (!solve_frame(frames[k], bilabial, goal, tasks, settings.max_steps)) s.unmet = true;
            constrained[k] = true;
        }
        segments.push_back(std::move(s));
    }
    for (auto& s : segments) {
        bool changed = false;
        for (std::size_t k : s.frames) {
            Frame d{};
            for (std::size_t p = 0; p < param_count; ++p) {
                d[p] = frames[k][p] - model[k][p];
                changed = changed || d[p] != 0.0;
            }
            s.deltas.push_back(d);
        }
        ++stats.segments;
        stats.segments_changed += changed ? 1 : 0;
        stats.segments_unmet += s.unmet ? 1 : 0;
    }

    // 2. The fall-off around them, on the task parameters only.
    const double reach = reach_sigmas * settings.transition_s;
    for (std::size_t k = 0; k < frames.size(); ++k) {
        if (constrained[k]) continue;
        const double t = times_s[k];
        Frame pull{};
        double weight = 0.0;
        for (const auto& s : segments) {
            const double t_first = times_s[s.frames.front()], t_last = times_s[s.frames.back()];
            const bool before = t < t_first;
            const double d = before ? t_first - t : t - t_last;
            if (d <= 0.0 || d > reach) continue;
            const double h = std::exp(-0.5 * (d / settings.transition_s) * (d / settings.transition_s));
            const Frame& delta = before ? s.deltas.front() : s.deltas.back();
            for (std::size_t p = 0; p < param_count; ++p) pull[p] += h * delta[p];
            weight += h;
        }
        if (weight == 0.0) continue;
        const double norm = std::max(1.0, weight);
        for (std::size_t i = 0; i < param_count; ++i)  // zero but for the tasks' parameters
            if (pull[i] != 0.0) frames[k][i] = std::clamp(model[k][i] + pull[i] / norm, params()[i].min, params()[i].max);
    }

    // 3. What changed.
    for (std::size_t k = 0; k < frames.size(); ++k) {
        bool changed = false;
        for (std::size_t p = 0; p < param_count; ++p)
            if (frames[k][p] != model[k][p]) {
                changed = true;
                stats.sum_abs_change[p] += std::fabs(frames[k][p] - model[k][p]);
            }
        stats.frames_changed += changed ? 1 : 0;
    }
    return stats;
}

ClosureConstrainedModel::ClosureConstrainedModel(std::shared_ptr<const ControlModel> model, LipTaskFunction tasks,
                                                 ClosureSettings settings)
    : m_model(std::move(model)), m_tasks(std::move(tasks)), m_settings(settings) {
    AVSI_ASSERT(m_model && m_tasks);
    set_provenance(m_model->provenance());
}

void ClosureConstrainedModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                                       std::vector<Frame>& out) const {
    m_model->evaluate(phones, times_s, out);
    constrain_closure(phones, times_s, m_tasks, m_settings, out);
}

}  // namespace avsi::synth
