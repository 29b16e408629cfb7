// The head tool: builds the built-in talking head (protocols/head/) from the
// CC0 MakeHuman assets (../shared/assets/makehuman/, see its README): the
// base mesh shaped by the macro targets of the variant (young adult male,
// female, or male with the dark skin texture), cut to head, neck and
// shoulders with the mouth interior; eyes, eyebrows, eyelashes, teeth,
// tongue and short hair fitted as proxies (.mhclo); every texture packed
// into one atlas PNG. The rig: each of the 10 articulatory parameters
// (synth/parameters.h) is a baked per-vertex displacement (a "blendshape"
// transform) of the matching face pose unit(s) of the skeleton (BVH pose
// units skinned with the .mhw weights), scaled so the parameter's range maps
// to the unit's natural range (parameter 1 = the unit at full weight; the
// negative end of the range = the opposite unit at full weight, or the
// positive shape extended where no opposite unit exists); the jaw opening is
// a rotation about the jaw bone's head (the unit's jaw rotation, calibrated
// so 1 opens the incisors ~20 mm as the parameter documents) plus the
// unit's other bone motions as a blendshape; the blink closes the upper lids
// on their bones (a rotation of each lid bone) and the tongue tip rises on
// its bones for dental and alveolar consonants. The articulation landmarks
// (inner-lip contours, corners, incisal edges…) are picked from the base
// mesh's topology around the mouth and the teeth proxy.
//
//   HeadBuildSettings s;
//   s.assets_dir = "../shared/assets/makehuman";
//   s.out_dir = "protocols/head";
//   build_head(s);   // writes head.obj, head.rig.json, head.png
#pragma once

#include <filesystem>
#include <string>

namespace avsi::stimuli {

enum class HeadVariant { Male, Female, DarkMale };

struct HeadBuildSettings {
    std::filesystem::path assets_dir;  // the MakeHuman assets folder
    std::filesystem::path out_dir;     // where the variant's files go
    HeadVariant variant = HeadVariant::Male;
    // Skin texture scale into the atlas (the source maps are 2048² for the whole body).
    float skin_texture_scale = 0.6f;
};

// The file stem of a variant: "head" (male, the default), "head-female", "head-dark".
std::string head_variant_stem(HeadVariant variant);
// Parses "male" / "female" / "dark-male"; throws UsageError otherwise.
HeadVariant head_variant_from_name(const std::string& name);

// Writes <stem>.obj, <stem>.rig.json and <stem>.png into out_dir. Throws
// InputError naming the asset file on bad or missing input.
void build_head(const HeadBuildSettings& settings);

}  // namespace avsi::stimuli
