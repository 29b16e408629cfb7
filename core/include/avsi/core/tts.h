// Text-to-speech front end through libespeak-ng: text → audio and a timed
// phone sequence in the project phone set, from espeak-ng's phoneme events.
#pragma once

#include <string>

#include "avsi/core/audio.h"
#include "avsi/core/phones.h"

namespace avsi {

struct TtsSettings {
    std::string voice = "en-us";
    int rate_wpm = 160;       // speaking rate, words per minute
    int pitch = 50;           // espeak-ng pitch, 0–99
    double lead_silence_s = 0.15;   // silence added before the speech
    double trail_silence_s = 0.15;  // silence kept after the speech
};

struct TtsResult {
    Audio audio;          // mono, espeak-ng's native rate (22050 Hz)
    PhoneSequence phones; // contiguous, from 0 to audio duration, `sil` at the edges
};

// Synthesises `text`. Throws InputError for an unknown voice or empty text.
TtsResult synthesize_speech(const std::string& text, const TtsSettings& settings = {});

}  // namespace avsi
