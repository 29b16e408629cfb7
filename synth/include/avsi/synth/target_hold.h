// Target hold: the rule model's closure mechanism, which makes it reach the
// articulatory targets a phone cannot do without (the lips' closure of
// /p b m/, the lower lip under the upper incisors for /f v/) in every
// segment, however short, and whatever the context.
//
// Smoothing and coarticulation models undershoot short segments: the
// Cohen-Massaro blend of dominance functions is a weighted mean of the
// neighbouring targets and cannot reach any of them while its neighbours
// still dominate (Cohen & Massaro 1993; the weakness Cosi et al. 2002 address
// with "temporal resistance" and the Charisma paper §3 mentions). Speakers
// do not undershoot lip closure: the lips move toward a virtual target beyond
// contact and are stopped by each other (Löfqvist & Gracco 1997). The hold
// gives any model's trajectory z(t) that property:
//
//     z'(t) = z(t) + s · Σ_i h_i(t) (T_i − z(t)) / max(1, Σ_i h_i(t))
//
// over the held segments i (phones in `phones`, parameters their target row
// specifies), with T_i the row's target, s the strength in [0, 1], and
//
//     h_i(t) = 1                                 start_i ≤ t ≤ end_i
//            = exp(−½ (d(t) / transition_s)²)    d(t) = distance to the segment
//
// except that a time inside a held segment counts only the segment(s) that
// hold it, so with s = 1 every frame inside a held segment shows the target
// exactly (between two adjacent held segments with different targets the
// track steps at their boundary),
// and the trajectory returns to the model's smoothly (C¹) outside it. With
// s = 0 (or no held phones) z' = z: the published model is unchanged.
//
// The targets come from the rule model's table (protocols/rule_targets.tsv:
// for /p b m/ the jaw, upper lip raise and lower lip depression, set beyond
// contact so the lips close from any context on the head's rig): this is
// the rule model's own mechanism (rule_model.h), part of the model as
// hand-set. A protocol condition's `closure = "hold"` is something else: it
// never writes another model's targets, it constrains the lips of the
// condition's own model (closure_constraint.h).
#pragma once

#include <filesystem>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "avsi/synth/control_model.h"
#include "avsi/synth/rule_model.h"

namespace avsi::synth {

struct TargetHoldSettings {
    std::set<std::string, std::less<>> phones{"P", "B", "M", "F", "V"};  // held phones (base symbols)
    double transition_s = 0.025;  // Gaussian fall-off of the hold outside the segment
    double strength = 1.0;        // s in [0, 1]
};

// Applies the hold to `frames` (one per time in `times_s`) in place.
void hold_targets(const PhoneSequence& phones, std::span<const double> times_s, const RuleModel::Table& targets,
                  const TargetHoldSettings& settings, std::vector<Frame>& frames);

// The default hold targets: protocols/rule_targets.tsv.
std::filesystem::path default_hold_targets_path();

}  // namespace avsi::synth
