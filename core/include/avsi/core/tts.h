// Text-to-speech front end: text → audio and a timed phone sequence in the
// project phone set, from one of two synthesisers.
//
// - espeak-ng (libespeak-ng, formant synthesis): phoneme events give each
//   phoneme's start (audio_position); a phoneme ends where the next one
//   starts, the last where the audio ends. Events carry no stress, so the
//   stress marks come from espeak_TextToPhonemes on the same text, aligned to
//   the events by edit distance.
// - Festival (libFestival; HTS statistical parametric voices such as
//   cmu_us_slt_arctic_hts, diphone voices such as kal_diphone): the phones
//   and their end times are the utterance's Segment relation, the stress that
//   of each segment's syllable, `pau` is silence.
// Then each stop or fricative after a vowel starts where the audio's energy
// falls away (core/onsets.h), unless `align_onsets` is off: the engines put
// the vowel-to-consonant transition on different sides of the boundary, the
// face should close the lips where the sound stops.
//
// Both engines keep global state; each utterance is synthesised in a child
// process from the same freshly initialised state, so the same text gives the
// same samples and times in any order, in any process, and synthesize_speech
// is safe to call from any thread (docs/tts.md).
//
//   avsi::TtsSettings s;
//   avsi::set_tts_voice(s, "festival:cmu_us_slt_arctic_hts");
//   avsi::TtsResult r = avsi::synthesize_speech("Come here John.", s);
//   // r.phones: sil K AH1 M HH IH1 R JH AA1 N sil, r.audio: 32000 Hz mono
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/phones.h"

namespace avsi {

enum class TtsEngine { Espeak, Festival };

struct TtsSettings {
    TtsEngine engine = TtsEngine::Espeak;
    std::string voice = "en-us";    // espeak-ng: a voice with a phone table (en-us, en, en-gb-x-rp, sv, de, …);
                                    // Festival: a voice of voice.list (cmu_us_slt_arctic_hts, kal_diphone)
    int rate_wpm = 160;             // espeak-ng: words per minute (80–450); Festival voices
                                    // speak at their own rate and take only this default
    int pitch = 50;                 // espeak-ng: pitch 0–99; Festival: only this default
    double lead_silence_s = 0.15;   // silence before the first phone (the engine's own
                                    // leading pause is padded or cut to this)
    double trail_silence_s = 0.15;  // silence after the last phone (padded or cut to this)
    bool align_onsets = true;       // the start of each stop and fricative after a vowel
                                    // moved to its acoustic onset (align_obstruent_onsets,
                                    // onsets.h); false: the engine's own segment times
};

struct TtsResult {
    Audio audio;          // mono, at the voice's own rate (espeak-ng 22050 Hz; Festival SLT
                          // 32000 Hz, kal 16000 Hz)
    PhoneSequence phones; // contiguous, from 0 to audio duration, `sil` at the edges
};

// Sets engine and voice from "<engine>:<voice>" ("espeak:en-us",
// "festival:cmu_us_slt_arctic_hts"). Throws InputError (path `where`, field
// "tts") for another engine or an empty voice; whether the voice is installed
// is checked when it is used.
void set_tts_voice(TtsSettings& settings, std::string_view spec, std::string_view where = "tts");

// "<engine>:<voice>" as set_tts_voice reads it.
std::string tts_voice_spec(const TtsSettings& settings);

// The phone table (protocols/languages/<code>/) a voice's name points to:
// Festival "en"; espeak-ng "en-us" -> "en", "sv" -> "sv", "sv+m3" -> "sv", "gmw/de" -> "de";
// "" when the name names no language with a table (the voice's own language
// is checked when it speaks).
std::string tts_voice_language(const TtsSettings& settings);

// What produced the speech, for manifests and input hashes.
struct TtsVoiceInfo {
    std::string engine;          // "espeak-ng" or "festival"
    std::string engine_version;  // espeak-ng "1.51"; Festival "2.5.0:release December 2017"
    std::string voice;
    std::string voice_sha256;    // Festival: SHA-256 over the voice's installed files; espeak-ng: ""
};

// Engine and voice names and versions; throws InputError (field "voice") for a
// voice that is not installed, listing the installed ones.
TtsVoiceInfo describe_tts_voice(const TtsSettings& settings);

// The installed voices the front end can use with `engine` (espeak-ng: the
// voices of the languages with a phone table; Festival: voice.list), sorted.
std::vector<std::string> installed_tts_voices(TtsEngine engine);

// Speech started by start_speech, to be taken with get(). Movable; destroying
// it untaken ends the synthesis.
class PendingSpeech {
public:
    PendingSpeech(PendingSpeech&&) noexcept;
    PendingSpeech& operator=(PendingSpeech&&) noexcept;
    ~PendingSpeech();

    // The result, as synthesize_speech gives it, or its error; once.
    TtsResult get();

private:
    struct State;  // tts.cpp
    explicit PendingSpeech(std::unique_ptr<State> state);
    friend PendingSpeech start_speech(const std::string& text, const TtsSettings& settings);
    std::unique_ptr<State> m_state;
};

// Starts synthesising `text` and returns: an espeak-ng voice speaks it in
// its child process while the caller goes on (`avsi synth --text` loads its
// model meanwhile); a Festival voice speaks it in get(). Throws here for
// empty text or silences out of range, and from get() what else
// synthesize_speech throws.
PendingSpeech start_speech(const std::string& text, const TtsSettings& settings = {});

// Synthesises `text`; with `align_onsets`, the phone times are the engine's
// with each vowel-to-obstruent boundary moved to the audio's onset. Throws InputError for an unknown voice or one without a phone table,
// settings out of range or not applicable to the engine, empty text, or a
// phone the mapping does not cover.
TtsResult synthesize_speech(const std::string& text, const TtsSettings& settings = {});

}  // namespace avsi
