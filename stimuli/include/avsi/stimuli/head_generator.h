// The generator of the built-in head (protocols/head/head.obj + head.rig.json).
// The mesh is built procedurally from shaped, deformed parametric surfaces:
// one skin surface parametrised in rings around the mouth (so the lips, their
// inner roll and the oral cavity are one continuous surface opening into the
// head), a superellipsoid skull with sculpted nose, brows, eye sockets, cheeks
// and chin, eyeballs with iris and pupil, eyelid shells, ears, neck, upper and
// lower tooth rows along a dental arch, and a tongue. The rig it writes is a
// Parke-style parameterisation (Parke 1982; Beskow 1995 §2) of the 10 study
// parameters. Regenerate with `scripts/make-head`.
#pragma once

#include <filesystem>

namespace avsi::stimuli {

struct HeadGeneratorSettings {
    int azimuth_segments = 112;  // around the mouth axis (even, so corners are sampled)
    int skin_rings = 68;         // from the lip border to the back of the head
};

// Writes the OBJ (per-vertex colours, one group per region) and the rig JSON.
void generate_head(const std::filesystem::path& obj_path, const std::filesystem::path& rig_path,
                   const HeadGeneratorSettings& settings = {});

}  // namespace avsi::stimuli
