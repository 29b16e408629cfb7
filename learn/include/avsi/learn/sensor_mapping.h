// Midsagittal EMA / marker coordinates → the articulatory parameters
// (Beskow §3.2 removes head motion with reference markers; §3.3–3.5 fit the
// face model's parameters to the markers). Here the fit is a documented
// direct mapping from four midsagittal sensors, usable with MOCHA-TIMIT
// (ui, li, ul, ll, reference bn + ui) and mngu0-style data.
//
// 1. Head motion (when reference sensors are given): per frame, the rigid 2-D
//    transform (rotation + translation, least squares / Procrustes) taking the
//    reference sensors to their mean position over the file is applied to
//    every sensor, so the head frame is fixed.
// 2. Orientation: the x axis counts as pointing forward when the upper lip's
//    mean x is larger than the upper incisor's (lips are in front of the
//    teeth), else backward; the y axis points up when the upper lip's mean y
//    is larger than the lower lip's. So the sign conventions of the recording
//    system do not matter.
// 3. Measures per frame, in mm (coordinates × mm_per_unit), each relative to
//    its rest value (the `rest_percentile` of the measure over the file for
//    openings, the median for positions):
//      jaw_rotation          = (ui−li vertical gap − rest) / jaw_opening_full_mm
//      jaw_thrust            = forward li displacement not explained linearly
//                              by the opening (rotation about the condyle moves
//                              the incisor back) / jaw_thrust_full_mm
//      upper_lip_raise       = upward ul displacement / lip_vertical_full_mm
//      lower_lip_depression  = downward ll displacement relative to li
//                              / lip_vertical_full_mm
//      upper_lip_retraction  = backward ul displacement / lip_protrusion_full_mm
//      lower_lip_retraction  = backward ll displacement relative to li
//                              / lip_protrusion_full_mm
//      lip_rounding          = mean forward displacement of ul and ll (the
//                              lower one relative to li) / lip_protrusion_full_mm:
//                              midsagittal data sees no lip width, and rounding
//                              goes with protrusion (spreading with retraction).
//    With lateral coordinates (3-D data: `lateral_suffix` set), also
//      jaw_shift             = lateral li displacement (toward the speaker's
//                              left positive) / jaw_shift_full_mm
//      mouth_corner_stretch_left/right = the corner sensor's lateral distance
//                              from the midline (the lips' mean lateral
//                              position) − rest / corner_stretch_full_mm
//    Without lateral data (MOCHA, mngu0) these three are missing; without a
//    corner sensor its stretch is missing (Haskins has only the left, ML).
//    Without an upper-incisor sensor (`upper_incisor` empty: head-corrected
//    data such as Haskins') the gap is measured from the lower incisor's
//    position in the head frame.
// 4. Frames whose break flag is 0 (no data) or any needed value is NaN give
//    NaN for the parameters that depend on them.
// The sensor track is resampled to `fps` by linear interpolation.
// Presets (`"preset"` in a corpus manifest's sensor_mapping): "mocha" (MOCHA-
// TIMIT as distributed: ui li ul ll, reference bn + ui, 1/100 mm) and
// "haskins" (the Haskins IEEE rate database: JAW UL LL ML, x front–back,
// z vertical, y lateral, mm, head-corrected so no reference sensors).
// docs/articulography.md tables which parameters each source drives.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/learn/est_track.h"
#include "avsi/synth/parameters.h"

namespace avsi::learn {

struct ParamTrack;

struct SensorMappingSettings {
    // Sensor names; channel names are <sensor><x_suffix> and <sensor><y_suffix>.
    std::string upper_incisor = "ui";
    std::string lower_incisor = "li";
    std::string upper_lip = "ul";
    std::string lower_lip = "ll";
    // Sensors fixed to the skull, for head-motion removal (MOCHA: bridge of
    // the nose and upper incisor). Empty: the data is already head-corrected.
    std::vector<std::string> reference_sensors = {"bn", "ui"};
    std::string x_suffix = "_x";   // horizontal (anterior–posterior) axis
    std::string y_suffix = "_y";   // vertical axis
    double mm_per_unit = 1.0;      // coordinate unit in mm (mngu0: mm)
    double rest_percentile = 5.0;  // rest value of an opening: this percentile
    double jaw_opening_full_mm = 20.0;     // incisor gap at jaw_rotation 1
    double jaw_thrust_full_mm = 5.0;       // forward jaw movement at jaw_thrust 1
    double lip_vertical_full_mm = 10.0;    // lip raise / depression at 1
    double lip_protrusion_full_mm = 6.0;   // lip retraction / protrusion at 1
    double fps = 60.0;                     // output frame rate
    // 3-D data: the lateral axis and the mouth-corner sensors (empty: none).
    std::string lateral_suffix;            // e.g. "_y" (Haskins); empty: 2-D data
    bool lateral_positive_left = true;     // the lateral axis points to the speaker's left
    std::string mouth_corner_left;         // e.g. "ML" (Haskins)
    std::string mouth_corner_right;
    double jaw_shift_full_mm = 5.0;        // sideways jaw movement at jaw_shift 1
    double corner_stretch_full_mm = 8.0;   // corner moving out at stretch 1
};

// The named preset ("mocha", "haskins"), or nullopt.
std::optional<SensorMappingSettings> sensor_mapping_preset(std::string_view name);

// The parameters a mapping produces (given every sensor it names is present).
std::array<bool, synth::param_count> drivable_parameters(const SensorMappingSettings& settings);

// Maps one file's sensor coordinates to parameters (see the file comment).
// Missing channels throw InputError naming `source` and the channels present.
ParamTrack map_sensors_to_params(const EstTrack& sensors, const SensorMappingSettings& settings,
                                 const std::string& source);

// Removes head motion in place: each frame is moved by the rigid transform
// that takes its reference sensors to their mean positions over the file.
void remove_head_motion(EstTrack& sensors, const SensorMappingSettings& settings,
                        const std::string& source);

}  // namespace avsi::learn
