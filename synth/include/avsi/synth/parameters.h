// The 10 articulatory control parameters of the reference study (Beskow,
// §2), defined once: name, unit, range and neutral value. Values are in
// normalised units where 0 is the neutral (rest) pose; the range is the full
// span used for RMSE-as-%-of-range and for the head rig.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string_view>

namespace avsi::synth {

enum class Param : int {
    JawRotation = 0,
    LipRounding,
    UpperLipRetraction,
    UpperLipRaise,
    LowerLipRetraction,
    LowerLipDepression,
    MouthCornerStretchLeft,
    MouthCornerStretchRight,
    JawThrust,
    JawShift,
    Count
};

inline constexpr std::size_t param_count = static_cast<std::size_t>(Param::Count);

struct ParamInfo {
    Param param;
    std::string_view name;         // snake_case, as in CSV headers and JSON
    std::string_view description;
    double min;                    // full range lower bound
    double max;                    // full range upper bound
    double neutral;                // rest pose

    double range() const { return max - min; }
};

// All 10 parameters in the study's order.
const std::array<ParamInfo, param_count>& params();
const ParamInfo& param_info(Param p);
// The parameter of that snake_case name, if any.
std::optional<Param> param_from_name(std::string_view name);

inline constexpr std::size_t index(Param p) { return static_cast<std::size_t>(p); }

}  // namespace avsi::synth
