// Festival (the Edinburgh speech synthesis system, through its C++ library
// libFestival) run out of the caller's process: text → waveform and the
// utterance's Segment relation. Private to avsi_core; tts.cpp maps the
// segments into the project phone set. Why out of process and how: see
// docs/tts.md ("Festival").
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace avsi::detail {

// One item of Festival's Segment relation.
struct FestivalSegment {
    std::string name;   // Festival phone name in the voice's phone set ("k", "ah", "pau")
    double end_s = 0.0; // the segment's `end` feature; it starts where the previous one ends
    bool stressed = false;  // stress of the syllable it belongs to (lexical stress 1 or 2)
};

struct FestivalUtterance {
    std::vector<std::int16_t> samples;  // the Wave relation's waveform, mono
    int sample_rate_hz = 0;
    std::vector<FestivalSegment> segments;
    std::string phone_set;              // the voice's phone set ("radio" for US English voices)
};

struct FestivalVoiceInfo {
    std::string festival_version;  // e.g. "2.5.0:release December 2017"
    std::string voice;
    std::string directory;         // where the voice's files are (voice-locations)
};

// Synthesises `text` with Festival voice `voice` (a name from voice.list, e.g.
// "cmu_us_slt_arctic_hts"). Throws InputError (field "voice") for a voice that
// is not installed, naming the installed ones, InputError (field "text") for
// text Festival cannot speak, std::runtime_error if Festival itself fails.
// Safe to call from any thread; calls run in parallel.
FestivalUtterance festival_synthesize(const std::string& text, const std::string& voice);

// The installed Festival voices (voice.list), sorted.
std::vector<std::string> festival_voices();

// One word as the voice's lexicon transcribes it.
struct FestivalWord {
    bool in_lexicon = false;            // in the lexicon or its addenda (else letter-to-sound)
    std::vector<FestivalSegment> phones;  // end_s is 0: a dictionary entry has no timing
};

// The voice's phone set and one transcription per word, in order. Words must
// not contain a newline. Throws as festival_synthesize.
std::pair<std::string, std::vector<FestivalWord>> festival_transcribe(const std::vector<std::string>& words,
                                                                      const std::string& voice);

// Festival's version and where `voice` is installed; throws as festival_synthesize.
FestivalVoiceInfo festival_voice_info(const std::string& voice);

}  // namespace avsi::detail
