// A face rig seen through a motion-capture marker layout: which markers a
// head carries, the model points each one is tied to, and a function that
// poses those points for a parameter frame. The contract between a head
// (stimuli/marker_layout.h builds it from a head and a layout file) and the
// marker fit (learn/marker_fit.h), so neither module needs the other.
//
// A face marker is tied to three model points v1, v2, v3 (a triangle of the
// surface): its virtual marker (Beskow 2004 §3.5, eq. 2) is
//     q = v1 + s (v2 − v1) + t (v3 − v1) + u n,
// n the unit normal of the triangle (the paper uses v1's vertex normal), with
// s, t, u fixed in the reference pose. `weights` give the marker's surface
// point Σ w_k v_k (the point the orientation fit, §3.4, pairs it with).
// Reference markers (the spectacle frame, §3) carry no model points: they
// only take the head's motion out; `frame_point` is where the layout puts
// them in the head's frame (for synthetic data and for drawing).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "avsi/synth/trajectory.h"

namespace avsi::synth {

struct ModelMarker {
    std::string name;
    bool reference = false;                  // on the spectacle frame: head motion only
    bool orientation = false;                // one of the orientation fit's strategic points (§3.4)
    std::array<std::size_t, 3> points{};     // into the posed points (face markers)
    std::array<double, 3> weights{1, 0, 0};  // the surface point's barycentric weights
    std::array<double, 3> frame_point{};     // reference markers: position in the head frame (mm)
};

struct MarkerModel {
    std::string source;                      // the layout file, for messages
    std::vector<ModelMarker> markers;
    std::size_t point_count = 0;
    // The posed model points for a parameter frame (normalised units), x y z
    // per point in mm, into `xyz` (resized to 3 × point_count). Thread-safe.
    std::function<void(const Frame& params, std::vector<double>& xyz)> pose;
    // The same with each parameter's two sides given apart: what the rig
    // does for values above rest follows `positive` (≥ 0), what it does
    // below rest `negative` (≤ 0), what it does on both sides their sum; so
    // pose_sides(max(y, 0), min(y, 0)) = pose(y). A rig made of one-sided
    // shapes has a kink at rest in each two-sided parameter; in the two
    // sides apart it is smooth, which is what the shape fit needs.
    std::function<void(const Frame& positive, const Frame& negative, std::vector<double>& xyz)> pose_sides;
    // The parameters whose rig has one-sided transforms.
    std::array<bool, param_count> two_sided{};

    // The index of a marker by name, or npos.
    std::size_t marker(const std::string& name) const {
        for (std::size_t i = 0; i < markers.size(); ++i)
            if (markers[i].name == name) return i;
        return npos;
    }
    static constexpr std::size_t npos = static_cast<std::size_t>(-1);
};

}  // namespace avsi::synth
