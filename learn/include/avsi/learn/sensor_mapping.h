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
//    mouth_corner_stretch_left/right and jaw_shift need lateral data: missing.
// 4. Frames whose break flag is 0 (no data) or any needed value is NaN give
//    NaN for the parameters that depend on them.
// The sensor track is resampled to `fps` by linear interpolation.
#pragma once

#include <string>
#include <vector>

#include "avsi/learn/est_track.h"

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
};

// Maps one file's sensor coordinates to parameters (see the file comment).
// Missing channels throw InputError naming `source` and the channels present.
ParamTrack map_sensors_to_params(const EstTrack& sensors, const SensorMappingSettings& settings,
                                 const std::string& source);

// Removes head motion in place: each frame is moved by the rigid transform
// that takes its reference sensors to their mean positions over the file.
void remove_head_motion(EstTrack& sensors, const SensorMappingSettings& settings,
                        const std::string& source);

}  // namespace avsi::learn
