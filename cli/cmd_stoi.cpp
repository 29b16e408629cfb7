// `avsi stoi`: the STOI (or ESTOI) of a degraded WAV against its clean version.
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/vocoder/stoi.h"
#include "command.h"
#include "one_of.h"
#include "vocoder_choices.h"

namespace avsi::cli {
namespace {

struct StoiOptions {
    std::string clean, degraded;
    bool extended = false;
    std::string channels = "mono";
};

const bool registered_stoi = register_command({
    "stoi",
    "Short-time objective intelligibility (STOI, or ESTOI with --extended) of a degraded file against the clean one",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<StoiOptions>();
        sub.add_option("clean", o->clean, "Clean reference WAV")->required()->check(CLI::ExistingFile);
        sub.add_option("degraded", o->degraded, "Degraded WAV (same rate and length)")->required()->check(CLI::ExistingFile);
        sub.add_flag("--extended", o->extended, "Extended STOI (Jensen & Taal 2016) instead of STOI");
        sub.add_option("--channels", o->channels,
                       "Several channels: mono (mixed down to one, a note says so) or keep (one value per channel, "
                       "a line each)")
            ->capture_default_str()
            ->check(one_of(channel_mode_names()));
        return [o] {
            const auto mode = vocoder::parse_channel_mode(o->channels);
            for (double d : vocoder::stoi_files(o->clean, o->degraded, {.extended = o->extended}, mode))
                fmt::print("{:.6f}\n", d);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
