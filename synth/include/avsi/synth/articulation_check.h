// The phonetic constraints a stimulus must meet on screen (DESIGN.md,
// "Validity checks"), checked on per-frame articulation measures in
// millimetres: what the face shows, measured on a head by the stimuli
// module (avsi/stimuli/articulation.h, from the rig's landmarks), and used by
// the stimulus builder, `avsi measure` and the objective evaluation's
// phonetic columns (learn). Pure computation: no head, no geometry here.
//
// The constraints (check_articulation): every /p b m/ segment has a sampled
// frame with the lips closed (maximum aperture over the central third
// ≤ 0.5 mm; a segment that holds no frame uses the frame nearest its centre:
// a closure the viewer never sees does not count); every /f v/ segment has a
// frame with the lower lip within 2 mm of the upper incisors (same frame
// rule); no frame has a negative aperture beyond rounding error (the lips
// press, they do not pass through each other); and rounded vowels (/uw w/)
// narrow the mouth and protrude the lips relative to spread /iy/ in the same
// utterance (compared at the frame nearest each segment's centre). In a
// Swedish utterance the close front vowels show their three-way contrast:
// outrounded /yː/ (YY) protrudes the lips beyond spread /iː/ (IY) by at
// least `outrounding_mm`, inrounded /ʉː/ (UX) narrows the mouth below /iː/'s
// width by at least `inrounding_mm` and protrudes less than /yː/ by at least
// `outrounding_mm` (lips compressed, not pushed forward; the Swedish
// phonetics of seed 001 §3, §4.4).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/phones.h"

namespace avsi::synth {

// One frame's measures, millimetres (mesh units of the head).
struct ArticulationMeasures {
    double time_s = 0.0;
    double aperture_mid_mm = 0.0;          // at the midline pair
    double aperture_min_mm = 0.0;          // smallest over the central third
    double aperture_max_mm = 0.0;          // largest over the central third
    double aperture_all_min_mm = 0.0;      // smallest over the whole contour (interpenetration check)
    double mouth_width_mm = 0.0;
    double upper_protrusion_mm = 0.0;
    double lower_protrusion_mm = 0.0;
    double jaw_opening_mm = 0.0;
    double lip_to_incisors_mm = 0.0;       // lower lip to the upper incisal edge
};

// The column names of an articulation CSV, in ArticulationMeasures' order.
const std::vector<std::string>& articulation_columns();

// Limits of the constraints (defaults as in DESIGN.md).
struct ArticulationLimits {
    double closure_mm = 0.5;         // /p b m/: central-third aperture at most this
    double labiodental_mm = 2.0;     // /f v/: lower lip to upper incisors at most this
    double interpenetration_mm = 0.05;  // aperture below −this counts as the lips passing through
    double outrounding_mm = 1.0;     // /yː/ protrusion beyond /iː/ (and beyond /ʉː/) at least this
    double inrounding_mm = 3.0;      // /ʉː/ mouth width below /iː/ at least this
};

// The lips at one vowel's segments: the mean over its segments of the frame
// nearest each centre.
struct VowelLips {
    std::size_t segments = 0;
    double width_mm = 0.0;
    double protrusion_mm = 0.0;  // mean of upper and lower lip protrusion
};

enum class SegmentClass { Bilabial, Labiodental };

// /p b m/ and /f v/: the phones whose lips the checks judge.
bool is_bilabial(std::string_view phone);
bool is_labiodental(std::string_view phone);

// One checked segment.
struct SegmentCheck {
    SegmentClass kind = SegmentClass::Bilabial;
    std::string phone;
    double start_s = 0.0;
    double end_s = 0.0;
    std::size_t best_frame = 0;   // the frame that came closest
    double best_mm = 0.0;         // its aperture (bilabial) or lip-to-incisor distance
    bool frame_inside = true;     // false: no frame inside, the nearest to the centre was used
    bool ok = false;
};

struct ArticulationSummary {
    std::size_t bilabials = 0, bilabials_closed = 0;
    std::size_t labiodentals = 0, labiodentals_reached = 0;
    double aperture_min_mm = 0.0;   // over every frame, whole contour
    double aperture_max_mm = 0.0;   // over every frame, midline
    std::size_t interpenetrating_frames = 0;
    // Rounding contrast (only when the utterance has both /uw w/ and /iy/).
    bool rounding_checked = false;
    bool rounding_ok = true;
    double width_rounded_mm = 0.0, width_spread_mm = 0.0;
    double protrusion_rounded_mm = 0.0, protrusion_spread_mm = 0.0;
    std::vector<SegmentCheck> segments;  // every /p b m f v/ segment
    // The Swedish close front vowels (checked when /iː/ and /yː/ or /ʉː/ occur).
    VowelLips spread_iy, outrounded_yy, inrounded_ux;
    bool close_front_checked = false;
    std::vector<std::string> close_front_problems;  // empty: the contrast holds

    std::size_t violations() const;
    // The largest best_mm over the segments of `kind` (0 when there are none):
    // how far the worst bilabial stayed from closing, or the worst /f v/ from contact.
    double worst_mm(SegmentClass kind) const;
    // One line per problem ("B at 1.230-1.290 s: aperture 2.1 mm at frame 37 > 0.5 mm"); empty if none.
    std::vector<std::string> problems(const ArticulationLimits& limits = {}) const;
    // The problems that make a stimulus broken rather than a model's result
    // (DESIGN.md, "Validity checks"): lips passing through each other, and,
    // when the condition asked for closure (closure = "hold"), a /p b m/ not
    // closed or an /f v/ without contact. A model shown as trained that
    // leaves a bilabial open is measured, not failed.
    std::vector<std::string> failures(bool closure_required, const ArticulationLimits& limits = {}) const;
};

// Checks the constraints of an utterance's measures (frame k at k / fps).
ArticulationSummary check_articulation(const PhoneSequence& phones, double fps,
                                       const std::vector<ArticulationMeasures>& measures,
                                       const ArticulationLimits& limits = {});

// Writes the measures as CSV (`time_s,aperture_mid_mm,…`), 4 decimals.
void write_articulation_csv(const std::filesystem::path& path, const std::vector<ArticulationMeasures>& measures);

// The order of "worst first": more violations, then the bilabial segment
// furthest from closing, then the labiodental furthest from contact.
bool worse_articulation(const ArticulationSummary& a, const ArticulationSummary& b);

}  // namespace avsi::synth
