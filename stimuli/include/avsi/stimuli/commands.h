// The library side of `avsi render` and `avsi contact-sheet`: settings
// structs filled by the CLI and one function each that does the work.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/contact_sheet.h"
#include "avsi/stimuli/layers.h"

namespace avsi::stimuli {

struct HeadFiles {
    std::filesystem::path obj = default_head_obj();
    std::filesystem::path rig = default_head_rig();
    std::filesystem::path gltf;     // a glTF head instead of obj + rig
    std::filesystem::path mapping;  // its blendshape mapping (empty: the default)
};

// The head the files name: the glTF head when given, else OBJ + rig.
Head load_head_files(const HeadFiles& files);

struct ExportHeadSettings {
    std::filesystem::path out_path;  // .glb (or .gltf)
    HeadFiles head;
};

// `avsi export-head`: the head as glTF with the mapping's ARKit-named targets.
void run_export_head(const ExportHeadSettings& settings);

struct RenderJobSettings {
    std::filesystem::path trajectory_path;  // CSV trajectory, or
    std::filesystem::path fap_path;         // MPEG-4 FAP v2.1 file
    std::filesystem::path audio_path;       // optional WAV/FLAC to mux
    std::filesystem::path phones_path;      // optional timed phones: the tongue tip follows them
    std::filesystem::path out_path;         // x.mp4, or a folder for PNG frames
    HeadFiles head;
    RenderSettings render;
    std::string camera = "front";
    VideoSettings video;
    BlinkSettings blinks;
    // Animation layers: a TOML file with a [layers] table (the protocol's
    // [condition.layers] syntax, docs/animation-layers.md); empty: speech and blinks.
    std::filesystem::path layers_path;
    std::uint64_t layer_seed = 1;  // seed of the gaze and idle head motion layers
};

// Renders a trajectory (or FAP stream) to an MP4 or a PNG sequence, with
// the layers of `layers_path` when given.
void run_render(const RenderJobSettings& settings);

struct MeasureJobSettings {
    std::filesystem::path trajectory_path;  // CSV trajectory, or
    std::filesystem::path fap_path;         // MPEG-4 FAP v2.1 file, or
    std::filesystem::path model_path;       // a control model driven by phones_path / text
    std::filesystem::path phones_path;      // timed phones (labels and checks; required with model_path unless text)
    std::string text;                       // text through the TTS front end (with model_path)
    std::string tts = "espeak:en-us";       // the voice that speaks `text` ("espeak:sv", "festival:…")
    double fps = 30.0;                      // frame rate of a model's trajectory
    std::filesystem::path out_path;         // measures CSV
    std::filesystem::path plot_path;        // optional SVG of the aperture over time
    HeadFiles head;
    ArticulationLimits limits;
};

// What run_measure found.
struct MeasureResult {
    std::size_t frames = 0;
    bool checked = false;  // phones were given, so the constraints were checked
    ArticulationSummary summary;
};

// `avsi measure`: the articulation measures of every frame of a trajectory,
// FAP stream or model output on a head, and (with phones) the constraints.
MeasureResult run_measure(const MeasureJobSettings& settings);

struct ContactSheetJobSettings {
    std::filesystem::path out_path;
    std::filesystem::path targets_path = default_sheet_targets();
    HeadFiles head;
    ContactSheetSettings sheet;
    std::string camera = "front";
};

// Renders the contact sheet PNG.
void run_contact_sheet(const ContactSheetJobSettings& settings);

}  // namespace avsi::stimuli
