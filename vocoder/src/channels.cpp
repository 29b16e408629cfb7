// Channel handling of vocode, mix and stoi (channels.h).
#include "avsi/vocoder/channels.h"

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"

namespace avsi::vocoder {

ChannelMode parse_channel_mode(std::string_view text, std::string_view option) {
    if (text == "mono") return ChannelMode::Mono;
    if (text == "keep") return ChannelMode::Keep;
    throw UsageError(fmt::format("{}: expected mono or keep, got \"{}\"", option, text));
}

Audio mix_down(const Audio& audio, const std::string& source, std::string_view purpose) {
    if (audio.channels <= 1) return audio;
    Audio out;
    out.sample_rate_hz = audio.sample_rate_hz;
    out.channels = 1;
    out.samples = audio.mono();
    log_info("{}: {} channels mixed down to mono {} (--channels keep keeps them)", source, audio.channels, purpose);
    return out;
}

}  // namespace avsi::vocoder
