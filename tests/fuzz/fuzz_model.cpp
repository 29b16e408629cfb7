// libFuzzer harness: the control model JSON loader (every model kind), then one synthesis.
#include "avsi/core/phones.h"
#include "avsi/synth/control_model.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto model = avsi::synth::load_model(avsi::fuzz::input_file("model.json", text));
        const avsi::PhoneSequence phones{{"sil", 0.0, 0.1, false}, {"M", 0.1, 0.2, false}, {"AA", 0.2, 0.4, true}};
        try {
            (void)model->synthesize(phones, 25.0);
        } catch (const avsi::InputError&) {
        }
    });
}
