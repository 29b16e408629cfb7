// The contact sheet: one labelled PNG showing the head at rest and at the
// articulatory targets of a set of phones, for checking at a glance that the
// articulations read (lip closure, labiodental contact, rounding, spread,
// jaw opening). Targets come from a CSV data file
// (protocols/head/contact_sheet_targets.csv): label, phone, then any of the
// 10 parameter columns (missing columns are 0, the rest value).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "avsi/stimuli/head.h"
#include "avsi/stimuli/renderer.h"

namespace avsi::stimuli {

struct SheetEntry {
    std::string label;  // e.g. "/p/"
    std::string phone;  // ARPAbet, e.g. "P"
    Pose pose;
};

struct ContactSheetSettings {
    int tile_width = 320;
    int tile_height = 320;
    int columns = 5;
    float framing_mm = 160.0f;  // world height shown in each tile: eyes to the neck below the chin
    CameraView camera = CameraView::Front;
};

// Reads the targets file; throws InputError with file:line on bad input.
std::vector<SheetEntry> read_sheet_targets(const std::filesystem::path& path);
std::filesystem::path default_sheet_targets();

// Renders every entry into a grid of labelled tiles.
Image render_contact_sheet(const Head& head, const std::vector<SheetEntry>& entries,
                           const ContactSheetSettings& settings = {});

}  // namespace avsi::stimuli
