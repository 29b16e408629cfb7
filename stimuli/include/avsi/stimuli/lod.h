// Level of detail for the talking head (Charisma paper §3: real-time mesh
// simplification with quadric error metrics, Garland & Heckbert 1997),
// through meshoptimizer's edge-collapse simplifier (meshopt_simplify,
// Debian's libmeshoptimizer-dev 0.18).
//
// What stays at full detail ("kept" triangles): every triangle of a group
// whose name says it is part of the mouth or the eyes (lips, inner lips,
// mouth cavity, teeth, tongue, eyes, cornea, lashes, brows, lids: see
// lod_keeps_group); every triangle with a vertex the articulation measures
// use (the rig's "articulation" landmarks), the lip contact moves
// ("lip_contact"), or an eye channel (blink, gaze) moves (the eyelids); and
// every triangle with a vertex within lod_keep_margin_mm of those (the skin
// under the brows and round the eyes and lips, so a simplified surface
// cannot come through the lashes and brows lying on it). The rest is
// simplified group by group with its border locked
// (meshopt_SimplifyLockBorder), so the seams between groups and against the
// kept regions stay exactly where they were and the surface has no hole it
// did not have. Alpha-blended layers (hair) and the skin within the margin
// under them are simplified apart, with a quarter of the error bound, so
// the skin does not come through the hair. The simplifier only removes
// vertices (the output indexes the original ones), so the simplified head
// is the original head with fewer triangles: unused vertices are dropped
// and every index — the triangles, each rig transform's sparse entries
// (weights, blendshape offsets), the articulation landmarks and the
// lip-contact points — is remapped. A vertex of a simplified head therefore
// poses to exactly the position its original vertex poses to, and the
// articulation measures are those of the full head.
//
// Levels: level k aims at 1/2^k of each part's simplifiable triangles but
// makes no collapse whose error exceeds lod_level_max_error_mm(k) (0.5 mm
// at level 1, doubling per level); k = 0 is the full head. A triangle
// budget takes the finest level within it; the automatic choice takes the
// coarsest level whose simplification error (meshoptimizer's, in mesh
// units) is under max_error_px pixels at the render's scale (pixels per mm
// at the target's depth: frame height / framing_mm). Distances are in mesh
// units: millimetres for the built-in and glTF heads.
//
//   LodResult lod = head_at_level(load_default_head(), 2);
//   OffscreenRenderer renderer(lod.head, settings);        // or RenderSettings::lod
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "avsi/stimuli/head.h"

namespace avsi::stimuli {

inline constexpr int max_lod_level = 3;
// Around the kept triangles, every vertex within this distance is kept too
// (mesh units: mm for the built-in and glTF heads).
inline constexpr double lod_keep_margin_mm = 4.0;

// The largest geometric error a level's collapses may make (mesh units):
// 0.5 mm at level 1, doubling per level (2 mm at level 3); 0 at level 0.
double lod_level_max_error_mm(int level);

// How a render chooses its level of detail. At most one of level,
// max_triangles and automatic is set; all unset = full detail (the default).
struct LodSettings {
    int level = 0;                  // 0 = full detail; 1..max_lod_level (coarser)
    std::size_t max_triangles = 0;  // > 0: the whole head in at most this many triangles
    bool automatic = false;         // by the head's size on screen
    double max_error_px = 0.5;      // automatic: the largest simplification error on screen, pixels
    bool full_detail() const { return level == 0 && max_triangles == 0 && !automatic; }
};

// Parses a level ("0" … "3") or "auto" into `lod`; throws UsageError naming
// `option` otherwise.
void parse_lod_level(const std::string& text, const std::string& option, LodSettings& lod);

// A simplified head and how it was made.
struct LodResult {
    Head head;                                 // the simplified head, rig and landmarks re-indexed
    std::vector<std::uint32_t> source_vertex;  // per vertex of `head`, its index in the full head
    std::string chosen_by = "full";            // "full", "level", "max_triangles" or "auto"
    int level = 0;                             // the level drawn (0 = full detail)
    std::size_t full_triangles = 0;            // the full head's
    std::size_t kept_triangles = 0;            // of those, kept at full detail
    std::size_t triangles = 0;                 // the simplified head's
    double error_mm = 0.0;                     // the largest simplification error (mesh units; 0 at full detail)
    double head_height_px = 0.0;               // automatic: the head's height on screen
};

// The simplifier and its version, for manifests ("meshoptimizer 0.18 …").
std::string lod_simplifier();

// Whether LoD keeps a group at full detail, by its name (case-insensitive:
// lip, teeth, tooth, tongue, mouth, inner, cavity, eye, cornea, iris, pupil,
// lash, brow, lid).
bool lod_keeps_group(const std::string& name);

// Per triangle of the head: 1 where LoD keeps it at full detail.
std::vector<char> lod_kept_triangles(const Head& head);

// The head at a level (0 = a copy of the full head); throws UsageError for a
// level outside [0, max_lod_level].
LodResult head_at_level(const Head& head, int level);

// The finest level of the head with at most `max_triangles` triangles (the
// full head when it has no more). Throws InputError naming the head's file
// when the budget is below the coarsest level (the message gives that
// level's count, the smallest budget that works).
LodResult head_within_budget(const Head& head, std::size_t max_triangles);

// The coarsest level whose simplification error is at most max_error_px at
// `pixels_per_mm` (level 0 when none is).
LodResult automatic_lod(const Head& head, double pixels_per_mm, double max_error_px);

// The head as `lod` asks for it, for a render whose frame is `height_px`
// pixels high showing `framing_mm` at the camera target's depth.
LodResult level_of_detail(const Head& head, const LodSettings& lod, int height_px, double framing_mm);

}  // namespace avsi::stimuli
