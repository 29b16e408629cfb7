// `avsi play`: play a trajectory, FAP stream or stimulus definition in a
// window with its audio (checking lip sync, slowed down, frame by frame), or
// edit a viseme set (`--edit-visemes set.json`).
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/experiment/player.h"
#include "command.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

struct PlayOptions {
    experiment::PlaySettings settings;
    std::string size;  // default: 1100x560, the editor 1240x800
    bool paused = false;
};

int run_play(PlayOptions& o) {
    auto& s = o.settings;
    if (o.size.empty()) o.size = s.edit_visemes.empty() ? "1100x560" : "1240x800";
    int w = 0, h = 0;
    char x = 0;
    if (std::sscanf(o.size.c_str(), "%d%c%d", &w, &x, &h) != 3 || x != 'x' || w < 320 || h < 240 || w > 8192 || h > 8192)
        throw UsageError("--size: expected WIDTHxHEIGHT (320x240 to 8192x8192), got \"" + o.size + "\"");
    s.window_width = w;
    s.window_height = h;
    if (!s.edit_visemes.empty()) {
        s.face_width = 480;
        s.face_height = 360;
    }
    // The face fits the window beside the controls (and above the strip).
    s.face_width = std::min(s.face_width, std::max(160, w - 460) & ~1);
    s.face_height = std::min(s.face_height, std::max(120, h - 80) & ~1);
    s.start_playing = !o.paused;
    if (!s.edit_visemes.empty()) {
        const auto& src = s.source;
        if (!src.trajectory_path.empty() || !src.fap_path.empty() || !src.protocol_path.empty() || !s.record.empty() ||
            !s.log.empty() || !s.audio_out.empty())
            throw UsageError("--edit-visemes opens the viseme-set editor alone: drop --traj, --fap, --protocol, "
                             "--record, --log and --audio-out");
    }
    const auto r = experiment::play(s);
    if (!s.edit_visemes.empty())
        log_info("viseme editor: {} refreshes{}", r.refreshes, r.saved ? ", set saved" : ", nothing saved");
    else
        log_info("play: {} refreshes, {} frame changes, {} audio samples sent{}", r.refreshes, r.frames_shown,
                 r.samples_sent, s.record.empty() ? std::string() : fmt::format(", {} frames recorded to {}",
                                                                               r.recorded_frames, s.record.string()));
    return 0;
}

const bool registered_play = register_command({
    "play",
    "Play a trajectory, FAP stream or stimulus with its audio in a window (lip-sync check), or edit a viseme set",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<PlayOptions>();
        auto& s = o->settings;
        auto& src = s.source;
        sub.add_option("--traj", src.trajectory_path, "Trajectory CSV to play")->check(CLI::ExistingFile);
        sub.add_option("--fap", src.fap_path, "MPEG-4 FAP v2.1 stream to play")->check(CLI::ExistingFile);
        sub.add_option("--audio-file", src.audio_path, "WAV/FLAC to play with --traj or --fap")->check(CLI::ExistingFile);
        sub.add_option("--phones", src.phones_path,
                       "Timed phones (TSV, TextGrid, HTK .lab) for the strip and the tongue tip, with --traj or --fap")
            ->check(CLI::ExistingFile);
        sub.add_option("--protocol", src.protocol_path,
                       "A stimulus definition: the protocol, with --sentence and --condition (or --stimuli/--stimulus)")
            ->check(CLI::ExistingFile);
        sub.add_option("--sentence", src.sentence, "Sentence id of the protocol's corpus");
        sub.add_option("--condition", src.condition, "Condition name of the protocol");
        sub.add_option("--stimuli", src.stimuli_dir,
                       "A stimulus folder built by `avsi build-stimuli`: play its entry --stimulus with the built WAV");
        sub.add_option("--stimulus", src.stimulus, "The manifest entry to play, e.g. s01/cohen-massaro.mp4");
        sub.add_option("--visemes", src.viseme_set_path,
                       "Viseme set naming the strip's visemes (default: protocols/visemes/mpeg4_14.json)")
            ->check(CLI::ExistingFile);
        sub.add_option("--edit-visemes", s.edit_visemes,
                       "Open the viseme-set editor on this set (the JSON the MPEG-4 Cohen-Massaro model reads)")
            ->check(CLI::ExistingFile);
        sub.add_option("--speed", s.speed, "Playback speed, 0.25 to 1 (audio time-stretched, pitch kept)")
            ->capture_default_str()
            ->check(CLI::Range(0.25, 1.0));
        sub.add_flag("--mute", s.muted, "Start muted (the audio clock still runs)");
        sub.add_option("--offset-ms", s.offset_ms, "A/V offset: the video this many ms later than the audio")
            ->capture_default_str()
            ->check(CLI::Range(-500.0, 500.0));
        sub.add_flag("--paused", o->paused, "Start paused at frame 0");
        sub.add_option("--audio", s.audio,
                       "Audio output: portaudio (the default device) or null (silent, simulated clock at --refresh-hz)")
            ->capture_default_str()
            ->check(one_of({"portaudio", "null"}));
        sub.add_option("--audio-device", s.audio_device, "PortAudio output device: an index or part of a name");
        sub.add_option("--refresh-hz", s.null_refresh_hz, "Refreshes per second of the simulated clock (--audio null)")
            ->capture_default_str()
            ->check(CLI::Range(1.0, 1000.0));
        sub.add_option("--audio-out", s.audio_out, "Write every audio sample sent to the device to this WAV");
        sub.add_option("--record", s.record, "Record the window and the audio as played to this MP4");
        sub.add_option("--script", s.script, "Scripted events, one a line (see below)")->check(CLI::ExistingFile);
        sub.add_option("--log", s.log, "Write one TSV row per screen refresh (frame shown, audio samples sent, …)");
        sub.add_option("--size", o->size, "Window size, WIDTHxHEIGHT (default 1100x560; the editor 1240x800)");
        sub.footer(experiment::play_help_text());
        return [o] { return run_play(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
