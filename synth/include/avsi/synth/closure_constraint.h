// The closure constraint: what `closure = "hold"` in a protocol condition
// does to a control model's output (DESIGN.md, "Validity checks"). It
// constrains only what closure needs and leaves the model's frame as it is
// everywhere else:
//
// - In every /p b m/ segment the lip aperture (the largest over the central
//   third of the mouth, what the articulation check judges closure by) is
//   brought down to aperture_goal_mm; in every /f v/ segment the lower lip's
//   distance to the upper incisors down to contact_goal_mm.
// - Only through the parameters that make that distance: jaw_rotation,
//   upper_lip_raise and lower_lip_depression for the aperture; jaw_rotation,
//   lower_lip_retraction and lower_lip_depression for the labiodental
//   contact. Every other parameter is the model's output bit for bit.
// - By the least change from the model's own frame: minimise
//   Σ_p (Δ_p / range_p)² over the task's parameters subject to
//   task(frame + Δ) ≤ goal. The task is measured on the head
//   (LipTaskFunction: the stimulus builder gives the head's articulation
//   meter), so the constraint is solved by Gauss-Newton steps on the
//   linearised task, Δ = −(task − goal)·D·g / (gᵀ·D·g) with g the task's
//   finite-difference gradient and D = diag(range_p²), each step clamped to
//   the parameters' ranges. A frame whose task already meets its goal is not
//   changed.
// - Which frames: every frame inside the segment [start, end), or, when no
//   frame falls inside a short segment, the frame nearest its centre (the
//   frame the articulation check judges it by). Outside those frames the
//   correction of the segment's nearest constrained frame fades as
//   exp(−½ (d / transition_s)²) with d the time to that frame, and stops at
//   d = 4·transition_s (where the weight is 3.4e-4); where the fall-offs of
//   several segments overlap their weighted corrections are averaged,
//   Σ h_i Δ_i / max(1, Σ h_i). Frames further away are not changed.
//
// No phone targets are involved: a model's closure comes from its own
// frame, moved the shortest way to contact. ClosureStats says what changed.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/synth/control_model.h"

namespace avsi::synth {

// The two lip tasks of a frame on a head, millimetres.
struct LipTaskMeasures {
    double aperture_mm = 0.0;         // largest lip aperture over the central third of the mouth
    double lip_to_incisors_mm = 0.0;  // lower lip to the upper incisal edge
};

// Measures a frame's lip tasks (thread-safe: called from the builder's workers).
using LipTaskFunction = std::function<LipTaskMeasures(const Frame&)>;

struct ClosureSettings {
    double aperture_goal_mm = 0.2;   // /p b m/: at most this (the check's closure limit is 0.5 mm)
    double contact_goal_mm = 1.0;    // /f v/: at most this (the check's contact limit is 2 mm)
    double transition_s = 0.025;     // σ of the fall-off outside the constrained frames
    int max_steps = 8;               // Gauss-Newton steps per frame
};

// The parameters each task moves (study order).
const std::vector<Param>& bilabial_task_params();
const std::vector<Param>& labiodental_task_params();

// What the constraint did to one utterance (or, summed, to a set).
struct ClosureStats {
    std::size_t frames = 0;                 // frames of the trajectory
    std::size_t frames_changed = 0;         // frames with any parameter changed
    std::size_t segments = 0;               // /p b m f v/ segments
    std::size_t segments_changed = 0;       // segments at least one of whose frames was moved
    std::size_t segments_unmet = 0;         // segments whose goal was not reached in some constrained frame
    std::array<double, param_count> sum_abs_change{};  // Σ |Δ_p| over the changed frames
    void add(const ClosureStats& other);
    // Mean |Δ_p| over the changed frames (0 when none changed).
    double mean_abs_change(Param p) const;
};

// Applies the constraint to `frames` (one per time in `times_s`) in place.
ClosureStats constrain_closure(const PhoneSequence& phones, std::span<const double> times_s,
                               const LipTaskFunction& tasks, const ClosureSettings& settings,
                               std::vector<Frame>& frames);

// A control model whose output is constrained to closure (the hold of a
// protocol condition, as a model for `avsi evaluate --closure-hold`).
class ClosureConstrainedModel : public ControlModel {
public:
    ClosureConstrainedModel(std::shared_ptr<const ControlModel> model, LipTaskFunction tasks,
                            ClosureSettings settings);

    std::string_view kind() const override { return m_model->kind(); }
    void evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                  std::vector<Frame>& out) const override;
    // The wrapped model's file: the constraint is a setting of its use, not of the model.
    std::string to_json_text() const override { return m_model->to_json_text(); }

    const ControlModel& model() const { return *m_model; }
    const ClosureSettings& settings() const { return m_settings; }

private:
    std::shared_ptr<const ControlModel> m_model;
    LipTaskFunction m_tasks;
    ClosureSettings m_settings;
};

}  // namespace avsi::synth
