// Acoustic onsets of stops and fricatives against their phone labels: how
// far the audio's own consonant onset lies from the time the labels (and so
// the talking face) put it. The onset of a stop or fricative that follows a
// vowel is where the vowel's energy falls away (stop closure, frication):
// the steepest drop of short-time log energy, comparing the energy in
// `window_s` before a time with the energy in `window_s` after it, searched
// between the centre of the vowel and the centre of the consonant (so a
// neighbouring boundary is never found instead). This is a simplified
// abrupt-landmark detector in the sense of Stevens' acoustic landmarks
// (Liu 1996, "Landmark detection for distinctive feature-based speech
// recognition"): one broadband energy instead of six bands.
//
//   for (const auto& o : obstruent_onsets(r.audio, r.phones)) use(o.offset_s());
//
// align_obstruent_onsets moves each such boundary to the onset found, so the
// labels (and the face) put the consonant where the audio has it: the
// synthesisers segment the vowel-to-consonant transition differently (HTS
// voices give it to the consonant, a median 19 ms before the closure;
// espeak-ng to the vowel, 13 ms after), and a lip-reader sees the lips meet
// where the sound stops.
#pragma once

#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/phones.h"

namespace avsi {

struct ObstruentOnset {
    std::size_t phone = 0;     // index of the stop or fricative in the sequence
    std::string symbol;        // its phone ("P", "S")
    std::string previous;      // the vowel before it
    bool stop = false;         // stop or affricate (else a fricative)
    double label_s = 0.0;      // where the labels put its start
    double acoustic_s = 0.0;   // where the audio's energy falls away
    double drop_db = 0.0;      // the energy drop there, dB
    double offset_s() const { return acoustic_s - label_s; }
};

struct OnsetSettings {
    double window_s = 0.010;   // energy window on each side of a candidate time
    double step_s = 0.0005;    // search step
};

// Every stop or fricative (phonetic features Stop or Fricative) directly after
// a vowel in `phones`, with its acoustic onset in `audio` (mono). Phones must
// be contiguous and cover the audio.
std::vector<ObstruentOnset> obstruent_onsets(const Audio& audio, const PhoneSequence& phones,
                                             const OnsetSettings& settings = {});

struct OnsetAlignment {
    double max_shift_s = 0.060;  // a boundary moves at most this far
    double min_drop_db = 6.0;    // an onset with a smaller energy drop is no landmark: the label stays
};

// Moves the start of every stop or fricative after a vowel (the end of the
// vowel) to its acoustic onset in `audio` (obstruent_onsets), when the energy
// drops there by at least `min_drop_db` and the onset lies within
// `max_shift_s` of the label; returns how many boundaries moved. The onset
// lies between the two phones' centres, so both keep at least half their length.
std::size_t align_obstruent_onsets(const Audio& audio, PhoneSequence& phones, const OnsetAlignment& alignment = {});

}  // namespace avsi
