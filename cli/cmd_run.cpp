// `avsi run`: run or resume one subject's session.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/core/protocol.h"
#include "avsi/experiment/runner.h"
#include "command.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

struct RunOptions {
    experiment::RunSettings settings;
    std::string protocol;
    std::string db;
    std::string stimuli;
    std::string script;
    std::string screenshots;
    bool windowed = false;
    bool fullscreen = false;
    int monitor = -1;
    std::string size = "1024x768";
    std::string audio_capture;
    bool list_audio_devices = false;
};

int run_run(RunOptions& o) {
    experiment::RunSettings& s = o.settings;
    if (o.list_audio_devices) {
        const auto devices = experiment::list_audio_devices();
        if (devices.empty()) fmt::print("no audio output devices (PortAudio finds none on this machine)\n");
        for (const auto& line : devices) fmt::print("{}\n", line);
        return 0;
    }
    if (o.protocol.empty()) throw UsageError("the protocol file is required");
    if (s.subject == 0) throw UsageError("--subject is required");
    if (!s.audio_device.empty() && s.audio != "portaudio")
        throw UsageError("--audio-device picks a PortAudio device; it needs --audio portaudio");
    s.protocol = o.protocol;
    if (o.windowed && o.fullscreen) throw UsageError("give --windowed or --fullscreen, not both");
    if (o.windowed) s.fullscreen = false;
    if (o.fullscreen) s.fullscreen = true;
    if (o.monitor >= 0) s.monitor = o.monitor;
    if (o.db.empty()) {
        const Protocol p = load_protocol(o.protocol);
        s.database = std::filesystem::path("data") / (p.name + ".sqlite");
    } else {
        s.database = o.db;
    }
    s.stimuli_dir = o.stimuli;
    s.script = o.script;
    s.screenshots = o.screenshots;
    s.audio_capture = o.audio_capture;
    int w = 0, h = 0;
    char x = 0;
    if (std::sscanf(o.size.c_str(), "%d%c%d", &w, &x, &h) != 3 || x != 'x' || w < 160 || h < 120)
        throw UsageError("--size: expected WIDTHxHEIGHT (at least 160x120), got \"" + o.size + "\"");
    s.window_width = w;
    s.window_height = h;
    const auto r = experiment::run_session(s);
    log_info("subject {}: {} responses this session, {} of {} answered{}; database {}", s.subject, r.answered,
             r.answered_before + r.answered, r.total, r.completed ? " — complete" : " — resumable",
             s.database.string());
    return 0;
}

const bool registered_run = register_command({
    "run",
    "Run or resume one subject's session (window, audio, responses stored in SQLite)",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<RunOptions>();
        auto& s = o->settings;
        sub.add_option("protocol", o->protocol, "Protocol file (TOML)")->check(CLI::ExistingFile);
        sub.add_option("--subject", s.subject, "Subject number (1-based; picks the subject's lists); required");
        sub.add_option("--db", o->db, "Session database (default: data/<experiment name>.sqlite)")->capture_default_str();
        sub.add_option("--stimuli", o->stimuli,
                       "Stimulus folder built by `avsi build-stimuli` (manifest.json + <sentence>/<condition>.mp4; "
                       "each clip is checked against the manifest's SHA-256)")
            ->capture_default_str();
        sub.add_flag("--test-pattern", s.test_pattern,
                     "Present a generated test clip (frame counter + tone bursts) instead of stimuli: dry runs and "
                     "timing checks");
        sub.add_flag("--windowed", o->windowed, "Run in a window (overrides session.fullscreen)");
        sub.add_flag("--fullscreen", o->fullscreen, "Run full screen (overrides session.fullscreen)");
        sub.add_option("--monitor", o->monitor, "Monitor for full screen (0 = primary; default: session.monitor)");
        sub.add_option("--size", o->size, "Window size when windowed, WIDTHxHEIGHT")->capture_default_str();
        sub.add_option("--audio", s.audio, "Audio output: portaudio (the default device) or null (silent, simulated "
                                           "clock at --refresh-hz)")
            ->capture_default_str()
            ->check(one_of({"portaudio", "null"}));
        sub.add_option("--audio-device", s.audio_device,
                       "PortAudio output device: an index or part of a name from --list-audio-devices (default: the "
                       "system's default output)")
            ->capture_default_str();
        sub.add_flag("--list-audio-devices", o->list_audio_devices,
                     "List the PortAudio output devices and exit (no protocol needed)");
        sub.add_option("--audio-capture", o->audio_capture,
                       "Write the samples sent to the audio device for each trial as trialNNN.wav in this folder "
                       "(checks that the stimulus audio is what plays)")
            ->capture_default_str();
        sub.add_option("--refresh-hz", s.null_refresh_hz, "Refresh rate of the simulated clock with --audio null")
            ->capture_default_str()
            ->check(CLI::Range(1.0, 1000.0));
        sub.add_option("--script", o->script, "Type responses from this file: one line per planned trial, '-' for "
                                              "an empty answer")
            ->capture_default_str();
        sub.add_option("--screenshots", o->screenshots, "Save each new screen as PNG in this folder")
            ->capture_default_str();
        return [o] { return run_run(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
