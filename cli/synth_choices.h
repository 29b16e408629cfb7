// The names of the articulatory parameters (synth/parameters.h), for the
// options that name one (`avsi synth --param`, `avsi evaluate
// --plot-param`) through one_of (one_of.h). Header-only, for commands whose
// helper links avsi_synth.
#pragma once

#include <string>
#include <vector>

#include "avsi/synth/parameters.h"

namespace avsi::cli {

// jaw_rotation, lip_rounding, … in the documented order.
inline std::vector<std::string> param_names() {
    std::vector<std::string> names;
    for (const auto& info : synth::params()) names.emplace_back(info.name);
    return names;
}

}  // namespace avsi::cli
