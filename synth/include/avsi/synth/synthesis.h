// `avsi synth` and `avsi fap2traj` as library calls: phones (a label file or
// text through the TTS front end) → control model → trajectory file (CSV or
// MPEG-4 FAP), and an optional SVG plot of one parameter with each
// segment's dominance function (like Fig. 2 of the Beskow paper and Fig. 4–5
// of the Charisma paper).
#pragma once

#include <filesystem>
#include <string>

#include "avsi/core/phones.h"
#include "avsi/synth/control_model.h"
#include "avsi/synth/fap.h"

namespace avsi::synth {

struct SynthesisSettings {
    std::filesystem::path model_path;
    std::filesystem::path phones_path;   // .tsv, .TextGrid or .lab; or
    std::string text;                    // text for the TTS front end
    std::string tts = "espeak:en-us";    // TTS engine and voice (with text), as set_tts_voice reads it
    std::filesystem::path wav_path;      // TTS audio out (with text), optional
    double fps = 60.0;
    std::filesystem::path out_path;
    std::string format = "auto";         // csv | fap | auto (by out_path extension)
    std::string fap_target = "mpeg4";    // fap: mpeg4 (Xface) | greta (25 fps, Greta's layout)
    bool fps_given = false;              // --fps was on the command line
    std::filesystem::path plot_path;     // optional SVG
    std::string plot_param = "jaw_rotation";
};

// Runs one synthesis as configured; throws InputError for bad input.
void run_synthesis(const SynthesisSettings& settings);

struct PlotSettings {
    double width_px = 1000.0;
    double height_px = 600.0;
    double sample_fps = 1000.0;  // curve sampling rate
};

// An SVG of one parameter: for dominance models, each segment's D_i(t) (top
// panel); the trajectory with each segment's target at its centre (bottom
// panel); phone labels and boundaries on the time axis.
std::string synthesis_plot_svg(const ControlModel& model, const PhoneSequence& phones, Param param,
                               double fps, const PlotSettings& settings = {});

struct FapConversionSettings {
    std::filesystem::path in_path;
    std::filesystem::path out_path;
    bool clamp = false;  // limit decoded parameters to their documented range
};

// `avsi fap2traj`: reads a FAP file and writes the trajectory CSV.
void run_fap_to_trajectory(const FapConversionSettings& settings);

}  // namespace avsi::synth
