// Optical motion capture: 3-D marker trajectories as Qualisys Track Manager,
// Vicon Nexus and OptiTrack Motive export them (the reference study recorded
// its speaker with a Qualisys system, 30 face markers and 5 on a spectacle
// frame at 60 fps; Beskow 2004 §3). docs/articulography.md, "Optical motion
// capture".
//
// Readers (chosen by the file's extension in read_marker_file):
//   .c3d  the C3D binary format (c3d.org, "The C3D File Format User Guide"):
//         512-byte blocks; block 1 the header (word 1: the parameter block
//         and the key 0x50; words 2–12: points, analog values per frame,
//         first and last frame, scale, data start, frame rate); the parameter
//         section (its 4-byte header holds the block count and the processor
//         type: 84 Intel, 85 DEC, 86 MIPS) lists groups and parameters, of
//         which POINT:USED, SCALE, RATE, DATA_START, FRAMES (or LONG_FRAMES),
//         LABELS (LABELS2, …) and UNITS are used here; the data section holds
//         per frame x, y, z and a residual word per point (int16 × SCALE when
//         SCALE > 0, float32 when SCALE < 0), then the analog samples. A
//         residual word < 0 marks the point invalid at that frame (a dropout).
//         Intel: little-endian, IEEE floats; DEC: little-endian integers and
//         VAX F floats; MIPS: big-endian, IEEE floats.
//   .tsv  Qualisys TSV export: NAME<TAB>value header lines (NO_OF_FRAMES,
//         NO_OF_MARKERS, FREQUENCY, MARKER_NAMES …), an optional column line
//         `Frame Time <name> X …`, then one row per frame (x y z per marker,
//         after the frame and time columns when the column line is there); in
//         mm. QTM writes a gap as empty cells or as 0 0 0: both are dropouts.
//   .csv  OptiTrack Motive CSV export (format version 1.2x): the key,value
//         first line (with "Export Frame Rate" and "Length Units"), then the
//         Type, Name, ID, property and `Frame,Time (Seconds),X,Y,Z…` rows;
//         the columns of Type "Marker" and property "Position" are read (rigid
//         bodies are not); empty cells are dropouts.
// Every reader converts to millimetres, checks every size against the file
// before using it and throws InputError naming the file and the block (C3D)
// or line (text) and field of the first problem.
#pragma once

#include <cstddef>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace avsi::learn {

// Marker positions per frame in mm; NaN coordinates mark a dropout.
struct MarkerRecording {
    double rate_hz = 0.0;                  // frames per second
    double start_s = 0.0;                  // time of frame 0
    std::vector<std::string> labels;       // one per marker
    std::size_t frames = 0;
    std::vector<double> xyz;               // frames × markers × 3

    std::size_t marker_count() const { return labels.size(); }
    double time_s(std::size_t frame) const { return start_s + static_cast<double>(frame) / rate_hz; }
    const double* point(std::size_t frame, std::size_t marker) const {
        return xyz.data() + (frame * labels.size() + marker) * 3;
    }
    double* point(std::size_t frame, std::size_t marker) {
        return xyz.data() + (frame * labels.size() + marker) * 3;
    }
    // Whether the marker was seen at the frame.
    bool seen(std::size_t frame, std::size_t marker) const { return point(frame, marker)[0] == point(frame, marker)[0]; }
    // The index of a marker by label, or npos.
    std::size_t marker(const std::string& label) const;
    static constexpr std::size_t npos = static_cast<std::size_t>(-1);
};

// The C3D processor types (parameter header byte 4).
enum class C3dProcessor { Intel = 84, Dec = 85, Mips = 86 };

// Reads a C3D file (see the file comment). Analog data is skipped.
MarkerRecording read_c3d(const std::filesystem::path& path);
// Reads a Qualisys TSV export.
MarkerRecording read_qualisys_tsv(const std::filesystem::path& path);
// Reads an OptiTrack Motive CSV export.
MarkerRecording read_motive_csv(const std::filesystem::path& path);
// Reads any of the three by extension (.c3d, .tsv, .csv); another extension
// throws InputError listing the supported ones.
MarkerRecording read_marker_file(const std::filesystem::path& path);

// Writes `time_s,<label>_x,<label>_y,<label>_z,…`, one row per frame, in mm
// (3 decimals); a dropout is three empty cells.
void write_markers_csv(const std::filesystem::path& path, const MarkerRecording& recording);

}  // namespace avsi::learn
