// The smooth step 3t² − 2t³ of t = (x − e0)/(e1 − e0) clamped to [0, 1], used
// for the falloffs of the head's regions (generator and rig weights).
#pragma once

#include <algorithm>

namespace avsi::stimuli {

inline float smoothstep(float e0, float e1, float x) {
    const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

}  // namespace avsi::stimuli
