// `avsi play`: a real-time player for checking a stimulus by eye and ear —
// the talking head drawn live in a GLFW window by the renderer's HeadDrawer,
// the audio through PortAudio, play/pause, frame steps both ways, speed
// 0.25×–1× with pitch-preserved (SoundTouch WSOLA time-stretch) or muted
// audio, the phone/viseme strip with the current phone highlighted, the 10
// articulatory parameters as live bars, an A/V offset for checking lip sync,
// and recording what it plays to MP4 (the Charisma paper's FAP-stream player,
// seed 000 §3). The viseme-set editor (viseme_editor.h) runs in the same
// window.
//
// The audio clock drives the picture: the frame shown is
//     k = floor((t_audio − offset)·fps),   t_audio = samples_consumed·speed / rate
// where samples_consumed counts the (time-stretched) output samples the
// device has taken, less its output latency. With the null device the clock
// is simulated — each screen refresh consumes rate/refresh_hz samples — so a
// scripted run under Xvfb is deterministic and every frame can be checked.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>


namespace avsi::experiment {

// What to play: exactly one of a trajectory CSV, a FAP stream, or a stimulus
// definition (a protocol's sentence × condition, optionally a built stimulus
// folder's manifest entry whose WAV is then played).
struct PlaySource {
    std::filesystem::path trajectory_path;  // CSV trajectory
    std::filesystem::path fap_path;         // MPEG-4 FAP v2.1 stream
    std::filesystem::path audio_path;       // WAV/FLAC played with a trajectory or FAP stream
    std::filesystem::path phones_path;      // timed phones (strip, tongue tip) for a trajectory or FAP stream
    std::filesystem::path protocol_path;    // stimulus definition: the protocol …
    std::string sentence;                   // … its sentence id …
    std::string condition;                  // … and condition name
    std::filesystem::path stimuli_dir;      // a built stimulus folder (manifest.json) …
    std::string stimulus;                   // … and its entry "<sentence>/<condition>.mp4"
    std::filesystem::path viseme_set_path;  // the viseme names in the strip (default: protocols/visemes/mpeg4_14.json)
};

// Pitch-preserving time-stretch (SoundTouch) of mono audio to play at
// `speed` (0.25 … 1): exactly round(n / speed) samples; speed 1 returns the
// input unchanged.
std::vector<float> time_stretch(const std::vector<float>& audio, int sample_rate_hz, double speed);

// The play head shared by the window and the audio device's callback: the
// stretched audio of the current speed, the output position in it, and the
// count of samples sent. All members are thread-safe.
class Transport {
public:
    Transport(std::vector<float> audio, int sample_rate_hz, double fps, int frame_count);

    // Fills `out` with the next n output samples (silence when paused, muted
    // or past the end) and advances the clock when playing.
    void pull(float* out, std::size_t n);
    void play();
    void pause();
    bool playing() const;
    // True once playback has run to the end (it pauses there).
    bool at_end() const;
    // Sets the speed (0.25 … 1), keeping the media time.
    void set_speed(double speed);
    double speed() const;
    void set_muted(bool muted);
    bool muted() const;
    // Moves the audio so that frame k is shown with A/V offset `offset_ms`:
    // to the middle of its interval, (k + 0.5)/fps + offset (steps land on
    // the frame, not on its edge); k is clamped to the frames.
    void seek_frame(int frame, double offset_ms = 0.0);
    // Media time of the audio at the output (s), given the device latency.
    double media_time_s(double latency_s = 0.0) const;
    // The frame for the current audio time: floor((t − offset)·fps) clamped to [0, frames − 1].
    int frame(double offset_ms, double latency_s = 0.0) const;
    // Output samples sent to the device so far (silence included while playing).
    std::int64_t samples_sent() const;
    // Output samples consumed while playing (the clock).
    std::int64_t samples_played() const;
    int sample_rate_hz() const { return m_rate; }
    // The samples sent so far (kept only after keep_sent(true)).
    std::vector<float> sent() const;
    void keep_sent(bool keep);

private:
    mutable std::mutex m_mutex;
    std::vector<float> m_source;
    std::vector<float> m_stretched;  // the source at m_speed
    int m_rate;
    double m_fps;
    int m_frames;
    double m_speed = 1.0;
    bool m_muted = false;
    bool m_playing = false;
    bool m_at_end = false;
    double m_pos = 0.0;  // output position in m_stretched (samples)
    std::int64_t m_sent = 0;
    std::int64_t m_played = 0;
    bool m_keep = false;
    std::vector<float> m_sent_samples;
};

// One line of a play script. Commands: play, pause, toggle, step N, seek K,
// speed X, mute on|off, offset MS, wait N (screen refreshes), wait-end (until
// playback reaches the end), screenshot PATH, quit; in the editor: select
// VISEME, set PARAMETER VALUE, width MM, height MM, map PHONE VISEME, undo,
// save [PATH].
struct ScriptEvent {
    int line = 0;
    std::string command;
    std::vector<std::string> args;
};

// Reads a play script (one command a line, '#' comments). Throws InputError
// naming file:line and the command for an unknown command or a bad argument.
std::vector<ScriptEvent> read_play_script(const std::filesystem::path& path, bool editor);

struct PlaySettings {
    PlaySource source;
    std::filesystem::path edit_visemes;     // run the viseme-set editor on this file instead
    double speed = 1.0;                     // 0.25 … 1
    bool muted = false;
    double offset_ms = 0.0;                 // video delay relative to the audio (−500 … 500)
    bool start_playing = true;              // start at once (scripts decide themselves)
    std::string audio = "portaudio";        // "portaudio" or "null" (simulated clock)
    std::string audio_device;               // PortAudio output device (index or name part)
    double null_refresh_hz = 60.0;          // screen refreshes per second of the simulated clock
    std::filesystem::path audio_out;        // write every sample sent to the device (WAV)
    std::filesystem::path script;           // scripted events (read_play_script)
    std::filesystem::path log;              // one TSV row per screen refresh
    std::filesystem::path record;           // record the window and the audio sent (MP4)
    int window_width = 1100;                // the player's; the editor's default is 1240x800
    int window_height = 560;
    int face_width = 640;                   // the face's drawing size in the window (the editor: 480x360)
    int face_height = 480;
};

struct PlayResult {
    int refreshes = 0;          // screen refreshes
    int frames_shown = 0;       // distinct frame changes
    std::int64_t samples_sent = 0;
    int recorded_frames = 0;
    bool saved = false;         // the editor saved the set
};

// Opens the window and plays (or edits) until the window closes, `q`/Esc is
// pressed or the script quits. Throws InputError for bad inputs and a
// missing display or audio device.
PlayResult play(const PlaySettings& settings);

// The key and script help shown by `avsi play --help`.
std::string play_help_text();

}  // namespace avsi::experiment
