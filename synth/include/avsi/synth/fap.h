// MPEG-4 Facial Animation Parameter (FAP) streams (ISO/IEC 14496-2; Pandzic
// & Forchheimer 2002; Charisma paper §3): the text format v2.1 that Xface
// reads and Greta writes,
//
//     # comment lines start with '#'
//     2.1 <name> <fps> <frames>
//     <68 mask entries, 0/1, for FAPs 1…68>            ┐ per frame
//     <frame number> <value of each masked FAP, in FAPU> ┘
//
// as the tools write it: Greta puts a file path with spaces into the name
// (the name is every token between the version and the last two numbers) and
// writes 69 mask entries (its FAP table has one more slot; a set 69th entry
// has a value, which is dropped with a warning) and one value for a set FAP 1
// or 2; Xface writes CRLF lines, a Windows path as the name and a mask line
// before every frame (masks may differ between frames). docs/fap.md lists
// what avsi reads and writes of the FAP specification.
//
// Values are integers in the FAP's unit (FAPU): MNS, MW, ENS, ES (a face
// distance / 1024) or AU (1e-5 rad). FAPs 1 (viseme) and 2 (expression) are
// high-level FAPs with several values each; avsi leaves them unmasked
// (mask 0), which is what Greta writes and what Xface's reader expects.
//
// The 10 articulatory parameters map linearly to the jaw and lip FAPs
// (3–17 inner lip and jaw, 51–60 outer lip), in millimetres of feature
// point displacement per parameter unit (FapMapping), divided by the FAPU of
// a face (FapUnits, a documented default adult face until the head model
// supplies its own). Lip FAPs are relative to the jaw (the lower lip rides
// on the jaw), as in the MPEG-4 feature-point definitions. The inverse
// (foreign FAP files → parameters) is the least-squares solution over the
// FAPs present; parameters no present FAP depends on stay neutral.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/synth/trajectory.h"

namespace avsi::synth {

inline constexpr int fap_count = 68;

// Key distances of the neutral face in millimetres; each FAPU is 1/1024 of
// one. Defaults: an average adult face (mouth width ≈ 50 mm, mouth-nose
// separation ≈ 20 mm, eye separation ≈ 63 mm, eye-nose separation ≈ 35 mm,
// iris diameter ≈ 12 mm), close to Xface's default head.
struct FapUnits {
    double mouth_nose_separation_mm = 20.0;  // MNS0
    double mouth_width_mm = 50.0;            // MW0
    double eye_nose_separation_mm = 35.0;    // ENS0
    double eye_separation_mm = 63.0;         // ES0
    double iris_diameter_mm = 12.0;          // IRISD0

    double mns_mm() const { return mouth_nose_separation_mm / 1024.0; }
    double mw_mm() const { return mouth_width_mm / 1024.0; }
};

enum class Fapu { MNS, MW };

// Feature-point displacement (mm) per unit of each parameter. The rows
// (which FAPs each parameter drives, with what sign) are fixed in fap.cpp
// and documented there; these are the magnitudes.
struct FapMapping {
    double jaw_open_mm = 12.0;           // chin drop (FAP 3) at jaw_rotation 1
    double lip_raise_mm = 6.0;           // upper lip mid raise (FAP 4/51) at upper_lip_raise 1
    double lip_depress_mm = 8.0;         // lower lip mid drop (FAP 5/52) at lower_lip_depression 1
    double corner_stretch_mm = 8.0;      // corner outward (FAP 6/7/53/54) at stretch 1
    double corner_raise_fraction = 0.25; // stretch also raises the corner (FAP 12/13/59/60)
    double rounding_mm = 10.0;           // corners inward (FAP 6/7/53/54) at lip_rounding 1
    double lip_protrusion_mm = 6.0;      // lip forward (FAP 16/17) at retraction −1
    double jaw_thrust_mm = 5.0;          // FAP 14
    double jaw_shift_mm = 5.0;           // FAP 15
    double side_fraction = 0.8;          // lip mid-left/right points move this fraction of the mid point
};

// One frame: which FAPs are present (index 0 = FAP 1) and their values in
// FAPU (integers in files avsi writes; foreign files may hold decimals).
struct FapFrame {
    std::array<bool, fap_count> mask{};
    std::array<double, fap_count> values{};
};

// A FAP stream. The mask may differ from frame to frame. FAPs 1 and 2 are
// never set: their values are skipped when reading (see read_fap).
struct FapStream {
    std::string name = "avsi";
    double fps = 25.0;
    std::vector<FapFrame> frames;
    // FAPs set in some frame of the file read (index 0 = FAP 1), including
    // FAPs 1 and 2 whose values are not kept; empty for streams avsi makes.
    std::array<bool, fap_count> present_in_file{};
};

// The MPEG-4 FAP groups (ISO/IEC 14496-2 Annex C): name and FAP numbers.
struct FapGroup {
    std::string_view name;
    int first;  // 1-based, inclusive
    int last;
};
const std::vector<FapGroup>& fap_groups();
// The MPEG-4 name of a FAP (1-based: 3 → "open_jaw").
std::string_view fap_name(int fap);
// FAPs set in the file that the parameter mapping does not use, by group
// ("head rotation (FAPs 48–50: head_pitch, head_yaw)"), in FAP order.
std::vector<std::string> unmapped_fap_groups(const FapStream& stream);

// Where a written FAP file is to be played.
enum class FapTarget {
    Mpeg4,  // the v2.1 text format with 68 mask entries (Xface, MPEG-4 players)
    Greta,  // Greta's conventions: 25 fps (Greta plays every file at 25 fps), 69 mask entries
};

// The FAPs (1-based numbers) avsi writes: the jaw and lip FAPs the mapping uses.
const std::vector<int>& mapped_faps();

// Parameters → FAP values (rounded to integer FAPU).
FapStream trajectory_to_fap(const Trajectory& trajectory, const FapUnits& units = {},
                            const FapMapping& mapping = {}, const std::string& name = "avsi");
// FAP values → parameters by least squares over the mapped FAPs present.
Trajectory fap_to_trajectory(const FapStream& stream, const FapUnits& units = {},
                             const FapMapping& mapping = {});

// The largest change in each parameter that rounding every FAP value to an
// integer FAPU can cause after the inverse mapping (the round-trip bound).
Frame fap_quantisation_bound(const FapUnits& units = {}, const FapMapping& mapping = {});

struct FapDecodeSettings {
    bool clamp = false;  // limit decoded parameters to their documented range
    FapUnits units;
    FapMapping mapping;
};
// Reads a FAP file and decodes it to parameters (fap_to_trajectory), warning
// (log) about FAP groups present but not mapped (unmapped_fap_groups) and
// about parameters outside their documented range (per parameter: frames,
// the worst value and its time); with `clamp` those are limited to the range.
Trajectory decode_fap_file(const std::filesystem::path& path, const FapDecodeSettings& settings = {});

// Writes a FAP v2.1 text file for `target`. Greta needs a 25 fps stream
// (anything else throws InputError naming the file, field "fps").
void write_fap(const std::filesystem::path& path, const FapStream& stream, FapTarget target = FapTarget::Mpeg4);
// Reads a FAP v2.1 text file (Xface's, Greta's, avsi's); malformed files
// throw InputError with file:line. Rules: '#' lines and blank lines are
// skipped; CR before the line end is dropped; the header is `2.1 name… fps
// frames` (the name may hold spaces); each frame is a line of at least 68
// mask flags (0/1; flags after the 68th are not MPEG-4 FAPs: a set one is
// warned about and its value dropped) and a line with the frame number
// (consecutive) and one value per set flag, except that a set FAP 1 (viseme)
// and FAP 2 (expression) take 4 and 6 values (the specification, Xface) or one
// each (Greta), whichever the line's count fits; they are read and dropped.
FapStream read_fap(const std::filesystem::path& path);

}  // namespace avsi::synth
