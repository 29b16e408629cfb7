// The level-of-detail options of `avsi render` and `avsi build-stimuli`
// (stimuli/lod.h, docs/level-of-detail.md). Header-only, for commands whose
// helper links avsi_stimuli.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "avsi/stimuli/lod.h"
#include "one_of.h"

namespace avsi::cli {

// --lod's values: the levels 0 to stimuli::max_lod_level, and auto.
inline std::vector<std::string> lod_level_names() {
    std::vector<std::string> names;
    for (int level = 0; level <= stimuli::max_lod_level; ++level) names.push_back(std::to_string(level));
    names.push_back("auto");
    return names;
}

// Adds --lod, --max-triangles and --lod-error-px to `sub` (`note` ends
// --lod's help); returns the function that puts --lod into `lod` once the
// command line is parsed (the other two go there directly). `lod` must
// outlive the returned function.
inline std::function<void()> add_lod_options(CLI::App& sub, stimuli::LodSettings& lod, const std::string& note = "") {
    auto level = std::make_shared<std::string>("0");
    sub.add_option("--lod", *level,
                   "Level of detail of the head: 0 = full detail; 1-3 = simplified (all but the lips, teeth and eyes: "
                   "about half of what is left per level, within 0.5, 1 or 2 mm); or auto = the coarsest level whose "
                   "simplification error is under --lod-error-px at the frame size (docs/level-of-detail.md)" +
                       note)
        ->capture_default_str()
        ->check(one_of(lod_level_names()));
    sub.add_option("--max-triangles", lod.max_triangles,
                   "The finest level of detail with at most this many triangles (0 = no budget; instead of --lod)")
        ->capture_default_str();
    sub.add_option("--lod-error-px", lod.max_error_px,
                   "--lod auto: the largest simplification error allowed on screen, in pixels")
        ->capture_default_str();
    return [level, &lod] { stimuli::parse_lod_level(*level, "--lod", lod); };
}

}  // namespace avsi::cli
