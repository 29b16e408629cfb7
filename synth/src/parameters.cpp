#include "avsi/synth/parameters.h"

#include "avsi/core/error.h"

namespace avsi::synth {

// Units are normalised: 0 is the rest pose (lips lightly closed, jaw closed,
// teeth together), 1 the largest excursion a speaker makes in that direction
// in ordinary speech; negative values move the other way where the
// articulator can. The head rig maps 1 unit to a physical displacement
// (stimuli/rig); the ranges below are the spans used for RMSE as % of range.
const std::array<ParamInfo, param_count>& params() {
    static const std::array<ParamInfo, param_count> table{{
        {Param::JawRotation, "jaw_rotation",
         "jaw opening by rotation about the condylar hinge (1 = widest speech opening, ~20 mm "
         "incisor gap)", -0.1, 1.0, 0.0},
        {Param::LipRounding, "lip_rounding",
         "narrowing and rounding of the lip opening (1 = fully rounded, negative = spread)", -0.5, 1.0,
         0.0},
        {Param::UpperLipRetraction, "upper_lip_retraction",
         "upper lip moved back (positive) or protruded (negative)", -1.0, 1.0, 0.0},
        {Param::UpperLipRaise, "upper_lip_raise",
         "upper lip raised above its rest position (positive) or pressed down (negative)", -0.5, 1.0,
         0.0},
        {Param::LowerLipRetraction, "lower_lip_retraction",
         "lower lip moved back and in, under the upper teeth for /f v/ (positive), or protruded "
         "(negative)", -1.0, 1.0, 0.0},
        {Param::LowerLipDepression, "lower_lip_depression",
         "lower lip lowered relative to the jaw (positive) or raised toward the upper lip "
         "(negative)", -0.5, 1.0, 0.0},
        {Param::MouthCornerStretchLeft, "mouth_corner_stretch_left",
         "left mouth corner pulled outward (positive) or inward (negative)", -0.5, 1.0, 0.0},
        {Param::MouthCornerStretchRight, "mouth_corner_stretch_right",
         "right mouth corner pulled outward (positive) or inward (negative)", -0.5, 1.0, 0.0},
        {Param::JawThrust, "jaw_thrust", "jaw moved forward (positive) or back (negative)", -1.0, 1.0,
         0.0},
        {Param::JawShift, "jaw_shift", "jaw moved sideways, to the speaker's left (positive)", -1.0,
         1.0, 0.0},
    }};
    return table;
}

const ParamInfo& param_info(Param p) {
    AVSI_ASSERT(p != Param::Count);
    return params()[index(p)];
}

std::optional<Param> param_from_name(std::string_view name) {
    for (const auto& info : params())
        if (info.name == name) return info.param;
    return std::nullopt;
}

}  // namespace avsi::synth
