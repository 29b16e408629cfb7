// The session runner: `avsi run protocol.toml --subject 7`. Loads the
// protocol, plans (or reloads) the subject's trials in the session database,
// resumes at the first trial without a response, and presents each stimulus
// in a GLFW window with Dear ImGui screens, each video frame shown at its time
// on the audio clock. A response is committed to the database before the next
// trial starts. Scripted mode types responses from a file and can save each
// screen as PNG; with the null audio device it runs headless under Xvfb.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "avsi/experiment/media.h"

namespace avsi::experiment {

struct RunSettings {
    std::filesystem::path protocol;
    int subject = 0;
    std::filesystem::path database;     // the experiment's session database
    std::filesystem::path stimuli_dir;  // built by `avsi build-stimuli`: manifest.json + <sentence>/<condition>.mp4
    bool test_pattern = false;          // present a generated test clip instead of stimuli
    std::optional<bool> fullscreen;     // overrides session.fullscreen
    std::optional<int> monitor;         // overrides session.monitor
    std::string audio = "portaudio";    // "portaudio" or "null"
    std::string audio_device;           // PortAudio output device (index or name part); "" = the default
    double null_refresh_hz = 60.0;      // refresh of the simulated clock (null audio)
    std::filesystem::path script;       // one response per planned trial, in plan order
    std::filesystem::path screenshots;  // save each new screen as PNG here
    std::filesystem::path audio_capture;  // write the samples sent to the audio device per trial (WAV) here
    int window_width = 1024;
    int window_height = 768;
};

// What a run did, for the CLI and tests.
struct RunResult {
    int session = 0;
    int answered_before = 0;  // responses already stored when the run started
    int answered = 0;         // responses committed by this run
    int total = 0;            // planned trials
    bool completed = false;   // every trial has a response
    bool quit = false;        // stopped from the pause screen or by closing the window
    int presentations = 0;
    int dropped_frames = 0;
    int repeated_frames = 0;
    double max_abs_av_offset_ms = 0.0;
    double mean_av_offset_ms = 0.0;
    std::string audio_device;
    int screenshots = 0;
};

// Runs (or resumes) one subject's session. Throws InputError for bad input
// (protocol, script, database of another experiment, missing stimulus).
RunResult run_session(const RunSettings& settings);

// Reads a response script: one line per planned trial in order; "-" or an
// empty line is an empty answer; lines starting with '#' are comments.
std::vector<std::string> read_script(const std::filesystem::path& path);

// One stimulus as listed in a stimulus folder's manifest.json.
struct ManifestEntry {
    std::string path;      // relative to the folder: <sentence>/<condition>.mp4
    int frames = 0;        // video frames
    double fps = 0.0;
    std::string sha256;    // of the MP4
    std::map<std::string, std::string> variants;  // adaptive list variable: audio variant path → SHA-256
};

// A stimulus folder's manifest.json (written by `avsi build-stimuli`).
struct StimulusManifest {
    std::string experiment;
    std::string sha256;    // of manifest.json itself
    std::map<std::string, ManifestEntry> stimuli;  // by path
};

// Reads DIR/manifest.json. Throws InputError if it is missing or not an avsi
// stimulus manifest.
StimulusManifest read_stimulus_manifest(const std::filesystem::path& dir);

// Stimuli from a folder built by `avsi build-stimuli`, decoded by the stimuli
// module. Checks each clip against its manifest entry (listed, SHA-256 and
// frame count) and its listed audio variants (SHA-256), so a stale or damaged
// stimulus is refused before it is shown.
class StimulusFolderOpener : public StimulusOpener {
public:
    explicit StimulusFolderOpener(std::filesystem::path dir);
    std::unique_ptr<FrameSource> open(const std::string& stimulus) override;
    const StimulusManifest& manifest() const { return m_manifest; }
    // Checks that every stimulus is listed, present and unchanged (SHA-256);
    // all problems are reported at once as an InputError.
    void verify(const std::vector<std::string>& stimuli) const;

private:
    std::filesystem::path m_dir;
    StimulusManifest m_manifest;
};


// The stimulus opener for a stimulus folder (the stimuli module's decoder),
// or the test pattern.
std::unique_ptr<StimulusOpener> make_stimulus_opener(const RunSettings& settings, double fps);

}  // namespace avsi::experiment
