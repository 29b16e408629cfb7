// libFuzzer harness: the audio readers (libsndfile: WAV, FLAC, whatever it
// detects): read_audio, and the block-wise AudioFileReader read through,
// seeked back and read again as the vocoder's two passes do.
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/audio_stream.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view bytes) {
        const auto path = avsi::fuzz::input_file("in.wav", bytes);
        try {
            const auto audio = avsi::read_audio(path);
            (void)audio.mono();
        } catch (const avsi::InputError& e) {
            if (std::string(e.what()).find("error: ") == std::string::npos) __builtin_trap();
        }
        avsi::AudioFileReader in(path);
        std::vector<float> block(256 * static_cast<std::size_t>(in.channels()));
        std::size_t total = 0;
        while (const std::size_t n = in.read(block.data(), 256)) total += n;
        if (total != in.frames()) __builtin_trap();
        in.seek(in.frames() / 2);
        while (in.read(block.data(), 256) != 0) {
        }
    });
}
