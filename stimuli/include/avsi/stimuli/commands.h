// The library side of `avsi render` and `avsi contact-sheet`: settings
// structs filled by the CLI and one function each that does the work.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/contact_sheet.h"

namespace avsi::stimuli {

struct HeadFiles {
    std::filesystem::path obj = default_head_obj();
    std::filesystem::path rig = default_head_rig();
};

struct RenderJobSettings {
    std::filesystem::path trajectory_path;  // CSV trajectory, or
    std::filesystem::path fap_path;         // MPEG-4 FAP v2.1 file
    std::filesystem::path audio_path;       // optional WAV/FLAC to mux
    std::filesystem::path out_path;         // x.mp4, or a folder for PNG frames
    HeadFiles head;
    RenderSettings render;
    std::string camera = "front";
    VideoSettings video;
    BlinkSettings blinks;
};

// Renders a trajectory (or FAP stream) to an MP4 or a PNG sequence.
void run_render(const RenderJobSettings& settings);

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
