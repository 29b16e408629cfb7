// What the face shows: geometric articulation measures of the posed head, per
// frame, in millimetres (mesh units), their plots, and the articulation QC
// page of a stimulus set (DESIGN.md, "Validity checks").
//
// The measures come from landmark vertices the rig names
// (ArticulationLandmarks, the rig file's "articulation" section), so they
// work on the built-in head and on a lab's own head alike:
//   - aperture: the vertical distance (along the head's up axis) between
//     paired points of the upper and lower inner-lip contours, what a frontal
//     viewer sees as the opening; negative where the lower contour lies above
//     the upper one (the lips pass through each other). Reported at the
//     midline and as the minimum and maximum over the central third of the
//     mouth width.
//   - mouth width: distance between the two corner landmarks.
//   - upper and lower lip protrusion: forward displacement (along the head's
//     forward axis) of the lips' midline vermilion points from rest.
//   - jaw opening: increase of the vertical gap between the upper and lower
//     incisal edges' midpoints from rest.
//   - lower lip to upper incisors: the smallest distance from the lower lip's
//     inner surface points to the upper incisal edge (a polyline).
//
// The constraints the measures are checked against (lip closure in
// /p b m/, labiodental contact in /f v/, no interpenetration, rounding) are
// in avsi/synth/articulation_check.h; the QC page of a stimulus set is here.
//
//   const auto& head = ...;                        // with an articulation section
//   ArticulationMeter meter(head);
//   auto measures = meter.measure(trajectory);     // one row per frame
//   auto summary = check_articulation(phones, trajectory.fps, measures);
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "avsi/core/phones.h"
#include "avsi/stimuli/head.h"
#include "avsi/synth/articulation_check.h"
#include "avsi/synth/closure_constraint.h"
#include "avsi/synth/trajectory.h"

namespace avsi::stimuli {

using synth::ArticulationLimits;
using synth::ArticulationMeasures;
using synth::ArticulationSummary;
using synth::check_articulation;
using synth::SegmentCheck;
using synth::SegmentClass;
using synth::worse_articulation;
using synth::write_articulation_csv;

// Poses only the landmark vertices of a head (the rig's transforms act on
// each vertex independently), so measuring a frame costs a few microseconds.
class ArticulationMeter {
public:
    // Throws InputError naming the rig file and every missing landmark when
    // the head's rig has no (or an incomplete) "articulation" section.
    explicit ArticulationMeter(const Head& head);

    ArticulationMeasures measure(const Pose& pose) const;
    // Measures every frame of a trajectory (frame k at k / fps), eyes open.
    std::vector<ArticulationMeasures> measure(const synth::Trajectory& trajectory) const;

private:
    struct Sparse {
        std::vector<std::uint32_t> slots;    // into m_rest
        std::vector<std::uint32_t> entries;  // the transform's entries (RigTransform::vertices) that move them
    };
    void pose_landmarks(const Pose& pose, std::vector<glm::vec3>& out) const;

    const Head& m_head;
    std::vector<std::uint32_t> m_vertices;  // the landmark vertices, in slot order
    std::vector<glm::vec3> m_rest;
    std::vector<Sparse> m_transforms;       // per rig transform, the landmarks it moves
    LipContactPoints m_contact;             // the landmarks the lip contact reads and moves
    // Slot ranges of each landmark set.
    std::vector<std::uint32_t> m_upper, m_lower, m_upper_edge, m_lower_edge, m_lip_surface;
    std::uint32_t m_corner_left = 0, m_corner_right = 0, m_upper_front = 0, m_lower_front = 0;
    std::size_t m_mid_pair = 0;
    std::vector<std::size_t> m_central_pairs;
    glm::vec3 m_up{0, 1, 0}, m_forward{0, 0, 1};
    double m_rest_upper_front = 0.0, m_rest_lower_front = 0.0, m_rest_incisor_gap = 0.0;
};

// An SVG plot of the aperture over time (midline, and the band between the
// central third's smallest and largest), with the phone labels along the
// bottom, the /p b m/ segments shaded, the closure limit drawn and the
// segments that break a constraint marked in red; the lower lip's distance
// to the upper incisors (dashed) through the /f v/ segments, and a circle at
// the frame each segment is judged by.
std::string aperture_plot_svg(const std::string& title, const PhoneSequence& phones,
                              const std::vector<ArticulationMeasures>& measures, const ArticulationSummary& summary,
                              const ArticulationLimits& limits = {});
// Writes aperture_plot_svg to `path`.
void write_aperture_plot(const std::filesystem::path& path, const std::string& title,
                         const PhoneSequence& phones, const std::vector<ArticulationMeasures>& measures,
                         const ArticulationSummary& summary, const ArticulationLimits& limits = {});

// One stimulus on the QC page.
struct QcStimulus {
    std::string path;       // the MP4, relative to the set's folder
    std::string condition;
    std::string sentence;   // id
    std::string text;
    ArticulationSummary summary;
    // The condition's post-processing policy ("as trained", "closure hold",
    // …), and whether it asked for closure (then a miss is a failure).
    std::string policy = "as trained";
    bool closure_required = false;
    synth::ClosureStats closure_change;  // what the constraint changed (held conditions)
    // For the plotted ones: the phones and every frame's measures.
    PhoneSequence phones;
    std::vector<ArticulationMeasures> measures;
};

// One of the segments that came least close to closure (/p b m/) or
// contact (/f v/) in a condition.
struct WorstSegment {
    std::string path;      // the stimulus
    std::string sentence;  // its sentence id
    std::string phone;
    double start_s = 0.0, end_s = 0.0;
    double distance_mm = 0.0;  // aperture (bilabial) or lower lip to upper incisors (labiodental) at its best frame
    bool met = false;          // within the limit
};

// A condition's articulation over its stimuli: what the model puts on the
// lips in running speech, as a result to read (and to report).
struct ConditionArticulation {
    std::string condition;
    std::string policy;
    bool closure_required = false;
    std::size_t stimuli = 0, bilabials = 0, bilabials_closed = 0, labiodentals = 0, labiodentals_reached = 0;
    std::size_t failing = 0;                  // stimuli with a failure (ArticulationSummary::failures)
    std::size_t interpenetrating_frames = 0;
    std::size_t rounding_checked = 0, rounding_ok = 0;  // stimuli with /uw w/ and /iy/, and those that contrast
    double aperture_min_mm = 0.0, aperture_max_mm = 0.0;
    std::vector<WorstSegment> worst_bilabials, worst_labiodentals;  // worst first
    synth::ClosureStats closure_change;
    double closure_rate() const { return bilabials ? double(bilabials_closed) / double(bilabials) : 0.0; }
    double contact_rate() const { return labiodentals ? double(labiodentals_reached) / double(labiodentals) : 0.0; }
};

// Per condition, in the order the conditions first appear, with up to
// `worst_listed` worst segments of each kind.
std::vector<ConditionArticulation> articulation_by_condition(const std::vector<QcStimulus>& stimuli,
                                                             std::size_t worst_listed = 5);

// The QC page of a stimulus set (HTML, self-contained): per condition its
// policy, the share of /p b m/ closed and /f v/ in contact over all its
// stimuli (results of the models, not constraints), the aperture range and
// the failures; each condition's worst segments (time, sentence, distance);
// every stimulus that fails, named with its segments; and the aperture plots
// of the stimuli given with measures (the worst ones). With `viseme_page`
// (a path relative to the page), a link to the set's objective viseme
// information (viseme_information.h).
std::string articulation_qc_html(const std::string& title, const std::vector<QcStimulus>& stimuli,
                                 const ArticulationLimits& limits = {}, const std::string& viseme_page = {});

}  // namespace avsi::stimuli
