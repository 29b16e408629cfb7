// Text-to-speech front end through libespeak-ng: text → audio and a timed
// phone sequence in the project phone set, from espeak-ng's phoneme events.
// Phoneme events give each phoneme's start (audio_position); a phoneme ends
// where the next one starts, the last where the audio ends. Events carry no
// stress, so the stress marks come from espeak_TextToPhonemes on the same text,
// aligned to the events by edit distance. espeak-ng has global state: calls are
// serialised by a mutex, so synthesize_speech is safe to call from any thread.
//
//   avsi::TtsResult r = avsi::synthesize_speech("Come here John.");
//   // r.phones: sil K AH1 M HH IH1 R JH AA1 N sil, r.audio: 22050 Hz mono
#pragma once

#include <string>

#include "avsi/core/audio.h"
#include "avsi/core/phones.h"

namespace avsi {

struct TtsSettings {
    std::string voice = "en-us";    // an English espeak-ng voice: en-us, en, en-gb-x-rp, …
    int rate_wpm = 160;             // speaking rate, words per minute (80–450)
    int pitch = 50;                 // espeak-ng pitch, 0–99
    double lead_silence_s = 0.15;   // silence before the first phone (espeak-ng's own
                                    // leading pause is padded or cut to this)
    double trail_silence_s = 0.15;  // silence after the last phone (padded or cut to this)
};

struct TtsResult {
    Audio audio;          // mono, espeak-ng's native rate (22050 Hz)
    PhoneSequence phones; // contiguous, from 0 to audio duration, `sil` at the edges
};

// Synthesises `text`. Throws InputError for an unknown or non-English voice,
// settings out of range, empty text, or a phoneme the mapping does not cover.
TtsResult synthesize_speech(const std::string& text, const TtsSettings& settings = {});

}  // namespace avsi
