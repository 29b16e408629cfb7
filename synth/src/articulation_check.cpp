// The phonetic constraints on per-frame articulation measures (see
// articulation_check.h).
#include "avsi/synth/articulation_check.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::synth {

bool is_bilabial(std::string_view phone) { return phone == "P" || phone == "B" || phone == "M"; }
bool is_labiodental(std::string_view phone) { return phone == "F" || phone == "V"; }

const std::vector<std::string>& articulation_columns() {
    static const std::vector<std::string> columns{
        "time_s",          "aperture_mid_mm",     "aperture_min_mm",     "aperture_max_mm",
        "aperture_all_min_mm", "mouth_width_mm",  "upper_protrusion_mm", "lower_protrusion_mm",
        "jaw_opening_mm",  "lip_to_incisors_mm"};
    return columns;
}

std::size_t ArticulationSummary::violations() const {
    std::size_t n = interpenetrating_frames > 0 ? 1 : 0;
    for (const auto& s : segments) n += s.ok ? 0 : 1;
    if (rounding_checked && !rounding_ok) ++n;
    return n + close_front_problems.size();
}

namespace {

std::string segment_problem(const SegmentCheck& s, const ArticulationLimits& limits) {
    const bool bilabial = s.kind == SegmentClass::Bilabial;
    return fmt::format("{} at {:.3f}-{:.3f} s: {} {:.2f} mm at frame {}{} > {:.1f} mm", s.phone, s.start_s, s.end_s,
                       bilabial ? "lip aperture" : "lower lip to upper incisors", s.best_mm, s.best_frame,
                       s.frame_inside ? "" : " (no frame inside; nearest to its centre)",
                       bilabial ? limits.closure_mm : limits.labiodental_mm);
}

std::string interpenetration_problem(const ArticulationSummary& s) {
    return fmt::format("the lips pass through each other in {} frame(s) (aperture down to {:.2f} mm)",
                       s.interpenetrating_frames, s.aperture_min_mm);
}

}  // namespace

std::vector<std::string> ArticulationSummary::problems(const ArticulationLimits& limits) const {
    std::vector<std::string> out;
    for (const auto& s : segments)
        if (!s.ok) out.push_back(segment_problem(s, limits));
    if (interpenetrating_frames > 0) out.push_back(interpenetration_problem(*this));
    if (rounding_checked && !rounding_ok)
        out.push_back(fmt::format("rounded /uw w/ do not narrow and protrude the lips relative to /iy/: width {:.1f} vs "
                                  "{:.1f} mm, protrusion {:.2f} vs {:.2f} mm",
                                  width_rounded_mm, width_spread_mm, protrusion_rounded_mm, protrusion_spread_mm));
    out.insert(out.end(), close_front_problems.begin(), close_front_problems.end());
    return out;
}

std::vector<std::string> ArticulationSummary::failures(bool closure_required, const ArticulationLimits& limits) const {
    std::vector<std::string> out;
    if (closure_required)
        for (const auto& s : segments)
            if (!s.ok) out.push_back(segment_problem(s, limits) + " although the condition asks for closure = \"hold\"");
    if (interpenetrating_frames > 0) out.push_back(interpenetration_problem(*this));
    return out;
}

namespace {

// The three-way contrast of the Swedish close front vowels (the header's rule).
std::vector<std::string> close_front_problems(const ArticulationSummary& s, const ArticulationLimits& limits) {
    std::vector<std::string> out;
    const VowelLips &i = s.spread_iy, &y = s.outrounded_yy, &u = s.inrounded_ux;
    if (y.segments > 0 && !(y.protrusion_mm >= i.protrusion_mm + limits.outrounding_mm))
        out.push_back(fmt::format("outrounded /yː/ does not protrude the lips beyond /iː/ by {:.1f} mm: protrusion "
                                  "{:.2f} vs {:.2f} mm",
                                  limits.outrounding_mm, y.protrusion_mm, i.protrusion_mm));
    if (u.segments > 0 && !(u.width_mm <= i.width_mm - limits.inrounding_mm))
        out.push_back(fmt::format("inrounded /ʉː/ does not narrow the mouth below /iː/ by {:.1f} mm: width {:.1f} vs "
                                  "{:.1f} mm",
                                  limits.inrounding_mm, u.width_mm, i.width_mm));
    if (u.segments > 0 && y.segments > 0 && !(u.protrusion_mm <= y.protrusion_mm - limits.outrounding_mm))
        out.push_back(fmt::format("inrounded /ʉː/ protrudes the lips like /yː/: protrusion {:.2f} vs {:.2f} mm "
                                  "(expected {:.1f} mm less)",
                                  u.protrusion_mm, y.protrusion_mm, limits.outrounding_mm));
    return out;
}

void add_vowel_lips(VowelLips& lips, const ArticulationMeasures& m) {
    ++lips.segments;
    lips.width_mm += m.mouth_width_mm;
    lips.protrusion_mm += 0.5 * (m.upper_protrusion_mm + m.lower_protrusion_mm);
}

void average_vowel_lips(VowelLips& lips) {
    if (lips.segments == 0) return;
    lips.width_mm /= static_cast<double>(lips.segments);
    lips.protrusion_mm /= static_cast<double>(lips.segments);
}

}  // namespace

ArticulationSummary check_articulation(const PhoneSequence& phones, double fps,
                                       const std::vector<ArticulationMeasures>& measures,
                                       const ArticulationLimits& limits) {
    AVSI_ASSERT(fps > 0);
    ArticulationSummary summary;
    if (measures.empty()) return summary;
    const std::size_t n = measures.size();
    // The frames inside [start, end), or the one nearest the centre.
    auto frames_of = [&](const Phone& ph, bool& inside) {
        std::size_t first = static_cast<std::size_t>(std::max(0.0, std::ceil(ph.start_s * fps - 1e-9)));
        std::size_t last = static_cast<std::size_t>(std::max(0.0, std::ceil(ph.end_s * fps - 1e-9)));  // exclusive
        first = std::min(first, n);
        last = std::min(last, n);
        inside = first < last;
        if (inside) return std::pair{first, last};
        const auto c = std::min(n - 1, static_cast<std::size_t>(std::max(0.0, std::round(ph.centre_s() * fps))));
        return std::pair{c, c + 1};
    };
    summary.aperture_min_mm = std::numeric_limits<double>::max();
    summary.aperture_max_mm = std::numeric_limits<double>::lowest();
    for (const auto& m : measures) {
        summary.aperture_min_mm = std::min(summary.aperture_min_mm, m.aperture_all_min_mm);
        summary.aperture_max_mm = std::max(summary.aperture_max_mm, m.aperture_mid_mm);
        if (m.aperture_all_min_mm < -limits.interpenetration_mm) ++summary.interpenetrating_frames;
    }
    double width_r = 0, width_s = 0, prot_r = 0, prot_s = 0;
    int count_r = 0, count_s = 0;
    for (const auto& ph : phones) {
        const bool bilabial = is_bilabial(ph.symbol), labiodental = is_labiodental(ph.symbol);
        if (bilabial || labiodental) {
            SegmentCheck c;
            c.kind = bilabial ? SegmentClass::Bilabial : SegmentClass::Labiodental;
            c.phone = ph.symbol;
            c.start_s = ph.start_s;
            c.end_s = ph.end_s;
            const auto [first, last] = frames_of(ph, c.frame_inside);
            c.best_mm = std::numeric_limits<double>::max();
            for (std::size_t k = first; k < last; ++k) {
                const double v = bilabial ? measures[k].aperture_max_mm : measures[k].lip_to_incisors_mm;
                if (v < c.best_mm) {
                    c.best_mm = v;
                    c.best_frame = k;
                }
            }
            c.ok = c.best_mm <= (bilabial ? limits.closure_mm : limits.labiodental_mm);
            (bilabial ? summary.bilabials : summary.labiodentals) += 1;
            if (c.ok) (bilabial ? summary.bilabials_closed : summary.labiodentals_reached) += 1;
            summary.segments.push_back(c);
        }
        if (VowelLips* lips = ph.symbol == "IY"   ? &summary.spread_iy
                              : ph.symbol == "YY" ? &summary.outrounded_yy
                              : ph.symbol == "UX" ? &summary.inrounded_ux
                                                  : nullptr) {
            bool inside = false;
            const auto [first, last] = frames_of(ph, inside);
            add_vowel_lips(*lips, measures[(first + last - 1) / 2]);
        }
        const bool rounded = ph.symbol == "UW" || ph.symbol == "W";
        const bool spread = ph.symbol == "IY";
        if (rounded || spread) {
            bool inside = false;
            const auto [first, last] = frames_of(ph, inside);
            const std::size_t k = (first + last - 1) / 2;
            const double protrusion = 0.5 * (measures[k].upper_protrusion_mm + measures[k].lower_protrusion_mm);
            if (rounded) {
                width_r += measures[k].mouth_width_mm;
                prot_r += protrusion;
                ++count_r;
            } else {
                width_s += measures[k].mouth_width_mm;
                prot_s += protrusion;
                ++count_s;
            }
        }
    }
    if (count_r > 0 && count_s > 0) {
        summary.rounding_checked = true;
        summary.width_rounded_mm = width_r / count_r;
        summary.width_spread_mm = width_s / count_s;
        summary.protrusion_rounded_mm = prot_r / count_r;
        summary.protrusion_spread_mm = prot_s / count_s;
        summary.rounding_ok = summary.width_rounded_mm < summary.width_spread_mm &&
                              summary.protrusion_rounded_mm > summary.protrusion_spread_mm;
    }
    for (VowelLips* lips : {&summary.spread_iy, &summary.outrounded_yy, &summary.inrounded_ux}) average_vowel_lips(*lips);
    summary.close_front_checked =
        summary.spread_iy.segments > 0 && (summary.outrounded_yy.segments > 0 || summary.inrounded_ux.segments > 0);
    if (summary.close_front_checked) summary.close_front_problems = close_front_problems(summary, limits);
    return summary;
}

void write_articulation_csv(const std::filesystem::path& path, const std::vector<ArticulationMeasures>& measures) {
    std::string out;
    for (const auto& c : articulation_columns()) out += (out.empty() ? "" : ",") + c;
    out += "\n";
    for (const auto& m : measures)
        out += fmt::format("{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}\n", m.time_s,
                           m.aperture_mid_mm, m.aperture_min_mm, m.aperture_max_mm, m.aperture_all_min_mm,
                           m.mouth_width_mm, m.upper_protrusion_mm, m.lower_protrusion_mm, m.jaw_opening_mm,
                           m.lip_to_incisors_mm);
    write_text_file(path, out);
}

double ArticulationSummary::worst_mm(SegmentClass kind) const {
    double worst = 0.0;
    for (const auto& c : segments)
        if (c.kind == kind) worst = std::max(worst, c.best_mm);
    return worst;
}

bool worse_articulation(const ArticulationSummary& a, const ArticulationSummary& b) {
    if (a.violations() != b.violations()) return a.violations() > b.violations();
    const double ab = a.worst_mm(SegmentClass::Bilabial), bb = b.worst_mm(SegmentClass::Bilabial);
    if (ab != bb) return ab > bb;
    return a.worst_mm(SegmentClass::Labiodental) > b.worst_mm(SegmentClass::Labiodental);
}

}  // namespace avsi::synth
