// The MPEG-4 Cohen-Massaro variant of the Charisma framework (seed 000,
// §3.4, eq. 5–8): segments are visemes; each segment's dominance is
//
//     D_sp(t) = α_sp·exp(−θ←·|τ|^c)  if τ >= 0,   α_sp·exp(−θ→·|τ|^c)  if τ < 0,
//     τ = t_start + duration/2 + t0_sp − t                        (eq. 5–6)
//
// with c = 1, θ← (anticipatory) and θ→ (carry-over) constants, t0 an offset
// of the peak from the segment centre, and the peak α_sp of each viseme its
// mouth ellipse area π·w·h (eq. 8) normalised over the viseme set; the
// trajectory is eq. 7, the dominance-weighted mean of the viseme targets.
//
// Normalisation: α = area / (largest area in the set), so the most open
// viseme has α = 1 and every α is in (0, 1]. (Min-max normalisation would
// give the least open viseme α = 0, a dominance that is zero everywhere, so
// its target could never be reached.) w and h are the outer-lip contour's
// width and height as Charisma measures a viseme's lip feature points, so a
// closed viseme (/p b m/) keeps a nonzero area. An optional floor raises
// small α (alpha_floor, 0 = none).
//
// Viseme sets are data (protocols/visemes/*.json):
//
//     {"name": "mpeg4-14", "source": "…",
//      "visemes": [{"id": 1, "name": "p_b_m", "phones": ["P", "B", "M"],
//                   "width_mm": 48, "height_mm": 14,
//                   "targets": {"jaw_rotation": 0.1, …all 10…}}, …]}
//
// Every project phone must map to exactly one viseme.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "avsi/synth/cohen_massaro.h"

namespace avsi::synth {

struct Viseme {
    int id = 0;
    std::string name;
    std::vector<std::string> phones;  // project phone symbols
    double width_mm = 0.0;            // outer-lip contour width
    double height_mm = 0.0;           // outer-lip contour height
    Frame targets{};                  // T_sp for the 10 parameters

    // Eq. 8: the ellipse area π·w·h in mm².
    double area_mm2() const;
};

struct VisemeSet {
    std::string name;
    std::string source;  // where the set and its phone mapping come from
    // The language whose phones it maps (protocols/languages/<code>/): every
    // phone of that table must be in a viseme. On disk "language", absent = "en".
    std::string language = "en";
    std::vector<Viseme> visemes;
    std::map<std::string, std::size_t, std::less<>> phone_to_viseme;  // index into visemes

    // α per viseme: area / largest area (see the file comment).
    std::vector<double> normalised_areas() const;
    // The viseme of a phone symbol; throws InputError if unmapped.
    const Viseme& viseme_of(std::string_view phone_symbol) const;
};

// Reads and validates a viseme set (every project phone mapped exactly once,
// widths/heights positive, targets in range). Errors name file and field.
VisemeSet load_viseme_set(const std::filesystem::path& path);

// The set as the JSON load_viseme_set reads (the keys in the file's order,
// 2-space indent): load_viseme_set of the text gives the set back.
std::string viseme_set_json_text(const VisemeSet& set);

// One segment of eq. 5–6 for one parameter: the dominance peak at the
// segment centre plus t0, θ← before it and θ→ after it, c = 1; T and α from
// the viseme (α by eq. 8). The model builds its segments with this, and
// training (learn/src/training.cpp) differentiates the same segments.
CmSegment mpeg4_segment(double centre_s, double t0_s, double target, double alpha,
                        double theta_anticipatory_per_s, double theta_carryover_per_s);

struct Mpeg4CmSettings {
    double theta_anticipatory_per_s = 25.0;  // θ←, before the peak
    double theta_carryover_per_s = 25.0;     // θ→, after the peak
    double t0_s = 0.0;                       // peak offset from the segment centre
    std::map<std::string, double, std::less<>> t0_s_by_viseme;  // overrides by viseme name
    double alpha_floor = 0.0;                // α = max(alpha_floor, normalised area)
};

// Kind "mpeg4-cohen-massaro". The model file names its viseme set:
//     {"kind": "mpeg4-cohen-massaro", "version": 1, "provenance": {…},
//      "viseme_set": "../visemes/mpeg4_14.json",   // relative to the model file
//      "theta_anticipatory_per_s": 25, "theta_carryover_per_s": 25,
//      "t0_s": 0, "t0_s_by_viseme": {}, "alpha_floor": 0}
class Mpeg4CohenMassaroModel : public DominanceModel {
public:
    Mpeg4CohenMassaroModel(VisemeSet visemes, std::string viseme_set_ref, Mpeg4CmSettings settings);

    std::string_view kind() const override { return "mpeg4-cohen-massaro"; }
    std::string to_json_text() const override;
    // τ = segment centre + t0; θ←, θ→ constant; c = 1; α and T from the viseme.
    std::array<std::vector<CmSegment>, param_count> segments_all(const PhoneSequence& phones) const override;

    const VisemeSet& viseme_set() const { return m_visemes; }
    const Mpeg4CmSettings& settings() const { return m_settings; }
    // α_sp of each viseme (same order as viseme_set().visemes).
    const std::vector<double>& alphas() const { return m_alphas; }

private:
    VisemeSet m_visemes;
    std::string m_viseme_set_ref;
    Mpeg4CmSettings m_settings;
    std::vector<double> m_alphas;
};

}  // namespace avsi::synth
