// How vocode, mix and stoi treat a file with more than one channel
// (`--channels mono|keep`). Default: mono, because intelligibility stimuli
// are presented diotically and STOI is defined for one signal.
//   mono  the channels are averaged into one before processing (a note names
//         the file), and the output is mono;
//   keep  each channel is processed: vocode gives every channel the same
//         noise carrier (a dual-mono input stays dual-mono, never dichotic),
//         mix adds the same noise to every channel, stoi scores each channel
//         against the same channel of the clean file.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "avsi/core/audio.h"

namespace avsi::vocoder {

enum class ChannelMode { Mono, Keep };

// "mono" or "keep"; throws UsageError naming `option` for anything else.
ChannelMode parse_channel_mode(std::string_view text, std::string_view option = "--channels");

// `audio` averaged to one channel (returned unchanged when it has one); when
// it had more, logs a note naming `source`.
Audio mix_down(const Audio& audio, const std::string& source, std::string_view purpose);

}  // namespace avsi::vocoder
