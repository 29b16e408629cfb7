// espeak-ng's C API, loaded with dlopen when a process first speaks, so that
// the many processes that never do (avsi synth --phones, vocode, score, …)
// do not load it and the 30 libraries it brings (PulseAudio, ALSA, X11 and
// D-Bus clients, through libpcaudio). Private to avsi_core; see docs/tts.md.
#pragma once

#include <espeak-ng/speak_lib.h>

namespace avsi::detail {

// The functions avsi calls, by their espeak_ names without the prefix.
struct EspeakLibrary {
    decltype(&::espeak_Initialize) Initialize = nullptr;
    decltype(&::espeak_SetSynthCallback) SetSynthCallback = nullptr;
    decltype(&::espeak_ListVoices) ListVoices = nullptr;
    decltype(&::espeak_SetVoiceByName) SetVoiceByName = nullptr;
    decltype(&::espeak_GetCurrentVoice) GetCurrentVoice = nullptr;
    decltype(&::espeak_SetParameter) SetParameter = nullptr;
    decltype(&::espeak_TextToPhonemes) TextToPhonemes = nullptr;
    decltype(&::espeak_SetPhonemeTrace) SetPhonemeTrace = nullptr;
    decltype(&::espeak_Synth) Synth = nullptr;
    decltype(&::espeak_Synchronize) Synchronize = nullptr;
    decltype(&::espeak_Info) Info = nullptr;
};

// The library (its SONAME, found as the dynamic linker finds libraries),
// loaded on the first call; thread-safe. Throws std::runtime_error saying
// what to install if it is missing or lacks one of the functions.
const EspeakLibrary& espeak_library();

}  // namespace avsi::detail
