#include "espeak_library.h"

#include <dlfcn.h>

#include <stdexcept>
#include <string>
#include <type_traits>

#include <fmt/format.h>

namespace avsi::detail {

namespace {

EspeakLibrary load() {
    void* handle = ::dlopen(AVSI_ESPEAK_NG_SONAME, RTLD_LAZY | RTLD_LOCAL);
    if (!handle) {
        const char* why = ::dlerror();
        throw std::runtime_error(fmt::format("espeak-ng could not be loaded ({}; is the libespeak-ng1 package "
                                             "installed? scripts/install-deps installs it)",
                                             why ? why : AVSI_ESPEAK_NG_SONAME));
    }
    EspeakLibrary library;
    auto bind = [handle](auto& function, const char* name) {
        void* symbol = ::dlsym(handle, name);
        if (!symbol)
            throw std::runtime_error(fmt::format("espeak-ng's library {} has no {} (espeak-ng 1.49 or later is needed)",
                                                 AVSI_ESPEAK_NG_SONAME, name));
        function = reinterpret_cast<std::remove_reference_t<decltype(function)>>(symbol);
    };
    bind(library.Initialize, "espeak_Initialize");
    bind(library.SetSynthCallback, "espeak_SetSynthCallback");
    bind(library.ListVoices, "espeak_ListVoices");
    bind(library.SetVoiceByName, "espeak_SetVoiceByName");
    bind(library.GetCurrentVoice, "espeak_GetCurrentVoice");
    bind(library.SetParameter, "espeak_SetParameter");
    bind(library.TextToPhonemes, "espeak_TextToPhonemes");
    bind(library.SetPhonemeTrace, "espeak_SetPhonemeTrace");
    bind(library.Synth, "espeak_Synth");
    bind(library.Synchronize, "espeak_Synchronize");
    bind(library.Info, "espeak_Info");
    return library;  // the handle stays open for the life of the process
}

}  // namespace

const EspeakLibrary& espeak_library() {
    static const EspeakLibrary library = load();
    return library;
}

}  // namespace avsi::detail
