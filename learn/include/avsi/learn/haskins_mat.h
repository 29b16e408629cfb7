// Haskins IEEE rate database EMA recordings (Tiede et al. 2017; the MVIEW
// layout): one MATLAB v5 .mat file per utterance holding a struct array
// named after the file, one element per channel, with fields
//
//     NAME      channel name: AUDIO, then the sensors TR TB TT UL LL ML JAW JAWL
//     SRATE     sample rate (Hz): 44100 for AUDIO, 100 for the sensors
//     SIGNAL    AUDIO: a sample vector; a sensor: N × 6, x (front–back),
//               y (lateral), z (vertical) in mm, then 3 orientation values
//     SOURCE    (not used)
//     SENTENCE  AUDIO: the sentence text
//     WORDS     AUDIO: struct array of LABEL (text) and OFFS ([start end], s)
//     PHONES    AUDIO: the same for phones (ARPAbet, `sp` for pauses)
//     LABELS    (not used)
//
// read through matio (Debian libmatio-dev). The sensors become an EstTrack
// with channels <NAME>_x, <NAME>_y, <NAME>_z (orientation dropped; a frame
// whose every coordinate is NaN, a dropout, is marked absent), for
// sensor_mapping.h's "haskins" preset. docs/articulography.md.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/labels.h"
#include "avsi/learn/est_track.h"

namespace avsi::learn {

struct HaskinsRecording {
    std::string variable;           // the struct array's name (the file's stem)
    std::string sentence;           // AUDIO.SENTENCE
    double audio_rate_hz = 0.0;     // AUDIO.SRATE
    std::size_t audio_samples = 0;  // length of AUDIO.SIGNAL
    std::vector<Interval> words;    // AUDIO.WORDS (line = element index, 1-based)
    std::vector<Interval> phones;   // AUDIO.PHONES
    double sensor_rate_hz = 0.0;    // the sensors' SRATE (all equal)
    std::vector<std::string> sensors;  // sensor names in file order
    EstTrack track;                 // the sensors' x, y, z
};

// Reads one recording. Problems (not a MAT file, no struct array, a missing
// field, a sensor SIGNAL that is not N × 6, sensors at different rates or
// lengths, OFFS not [start end]) throw InputError naming the file and the
// element ("element 3 (TT) SIGNAL"); line is the element's 1-based index.
HaskinsRecording read_haskins_mat(const std::filesystem::path& path);

}  // namespace avsi::learn
