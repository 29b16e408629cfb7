// espeak-ng's transcription of single words (tts.cpp, where the engine's
// child processes live); transcription.cpp calls it. Private to avsi_core.
#pragma once

#include <string>
#include <vector>

#include "avsi/core/transcription.h"

namespace avsi::detail {

// One transcription per word, in order, by the espeak-ng voice of
// `settings`, in one child process: the phones espeak_TextToPhonemes gives,
// mapped into the project phone set as a synthesised word's phoneme events
// are, and whether espeak-ng's dictionary holds the word (its phoneme trace
// says "Found") or its rules spelled it out ("Translate"). Throws InputError
// (field "voice") for a voice not installed or without a phone table, and
// (field "word") for a word with an unmapped phone or none at all.
std::vector<WordTranscription> espeak_transcribe(const std::vector<std::string>& words, const TtsSettings& settings);

}  // namespace avsi::detail
