// What the session runner presents and how it keeps time: a FrameSource gives
// a stimulus' video frames (RGBA + presentation time) and its audio; an
// AudioOutput plays audio and owns the clock the frames are scheduled on
// (the DAC clock for PortAudio; a simulated clock advanced one refresh per
// buffer swap for the null device, for headless runs and tests); the
// FramePacer picks the frame for each screen refresh from the audio clock and
// measures the result (dropped and repeated frames, audio–video offset).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "avsi/experiment/store.h"

namespace avsi::experiment {

struct VideoFrame {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgba;  // width·height·4, top row first
    double pts_s = 0.0;
    int index = 0;
};

// One stimulus clip, read front to back.
class FrameSource {
public:
    virtual ~FrameSource() = default;
    virtual int width() const = 0;
    virtual int height() const = 0;
    virtual double fps() const = 0;
    virtual int frame_count() const = 0;
    // Decodes the next frame in presentation order; false after the last.
    virtual bool next_frame(VideoFrame& frame) = 0;
    // The whole audio track, mono.
    virtual const std::vector<float>& audio() const = 0;
    virtual int sample_rate() const = 0;
};

// Opens the clip of a stimulus path relative to the stimulus folder.
class StimulusOpener {
public:
    virtual ~StimulusOpener() = default;
    virtual std::unique_ptr<FrameSource> open(const std::string& stimulus) = 0;
};

struct TestPatternSettings {
    int width = 320;
    int height = 240;
    double fps = 30.0;
    double duration_s = 1.0;
    int sample_rate = 48000;
    double click_hz = 1000.0;    // a 10 ms tone burst at each frame onset
};

// A generated clip for dry runs and timing checks: each frame a different
// colour with its index as a row of white/black blocks, the audio a tone
// burst at every frame onset (so a photodiode and a microphone can check sync).
std::unique_ptr<FrameSource> make_test_pattern(const TestPatternSettings& settings);

// An opener that gives every stimulus the test pattern.
class TestPatternOpener : public StimulusOpener {
public:
    explicit TestPatternOpener(TestPatternSettings settings) : m_settings(settings) {}
    std::unique_ptr<FrameSource> open(const std::string& stimulus) override;

private:
    TestPatternSettings m_settings;
};

// Audio playback that owns the presentation clock.
class AudioOutput {
public:
    virtual ~AudioOutput() = default;
    virtual std::string name() const = 0;
    // The clock frames are scheduled on, in seconds.
    virtual double now_s() = 0;
    // Plays `samples` (mono) so that sample 0 reaches the DAC at `at_s`
    // (or as soon as possible after it).
    virtual void play(const std::vector<float>& samples, int sample_rate, double at_s) = 0;
    // When sample 0 reached (or will reach) the DAC, once known.
    virtual std::optional<double> onset_s() = 0;
    // True while samples remain to be played.
    virtual bool playing() = 0;
    virtual void stop() = 0;
    // Called after each buffer swap with the refresh period; the null device
    // advances its simulated clock by it.
    virtual void after_flip(double refresh_period_s) { (void)refresh_period_s; }
    // The extra time to schedule audio ahead of the next flip (output latency).
    virtual double lead_s() const { return 0.0; }
    // How the last onset was scheduled (requested time, DAC time, latency),
    // for the log; "" when there is nothing to measure (simulated clock).
    virtual std::string onset_detail() { return ""; }
};

// No sound; a simulated clock that moves one refresh per flip.
class NullAudioOutput : public AudioOutput {
public:
    std::string name() const override { return "null (simulated clock)"; }
    double now_s() override { return m_now_s; }
    void play(const std::vector<float>& samples, int sample_rate, double at_s) override;
    std::optional<double> onset_s() override { return m_onset_s; }
    bool playing() override;
    void stop() override;
    void after_flip(double refresh_period_s) override { m_now_s += refresh_period_s; }

private:
    double m_now_s = 0.0;
    std::optional<double> m_onset_s;
    double m_duration_s = 0.0;
};

// PortAudio on an output device, scheduling onsets with the stream's output
// DAC timestamps. `device` is a device index or a case-insensitive part of a
// device name (see list_audio_devices); "" is the default output device.
// Throws InputError naming the device if it cannot be found or opened.
std::unique_ptr<AudioOutput> make_portaudio_output(const std::string& device = "");

// A PortAudio output stream whose callback asks `pull` for each buffer of
// mono samples (the player's transport keeps the clock).
class PullAudioStream {
public:
    virtual ~PullAudioStream() = default;
    virtual std::string name() const = 0;
    // The stream's output latency (s): how long a pulled sample takes to reach the DAC.
    virtual double latency_s() const = 0;
};

// Opens and starts a pull stream on `device` (as make_portaudio_output).
// Throws InputError naming the device if it cannot be found or opened.
std::unique_ptr<PullAudioStream> open_portaudio_pull_stream(const std::string& device, int sample_rate_hz,
                                                            std::function<void(float*, std::size_t)> pull);

// The PortAudio output devices, one line each: "index: name (host API,
// channels, default rate, low latency)", the default marked. Throws
// InputError if PortAudio cannot start.
std::vector<std::string> list_audio_devices();

// Chooses frames from the audio clock and measures what was shown.
class FramePacer {
public:
    FramePacer(double fps, int frame_count, double refresh_hz);
    void start(double audio_onset_s);
    // The frame to show at a flip expected at `flip_s`: −1 before the onset,
    // frame_count() after the clip.
    int frame_for(double flip_s) const;
    // Frame `frame` (with its pts) reached the screen at `flip_s`.
    void flipped(int frame, double pts_s, double flip_s);
    int frame_count() const { return m_frame_count; }
    // The timing summary of the presentation so far.
    Presentation summary() const;

private:
    double m_fps;
    int m_frame_count;
    double m_refresh_hz;
    double m_onset_s = 0.0;
    std::vector<int> m_flips_per_frame;
    std::vector<FrameFlip> m_first_flips;
};

}  // namespace avsi::experiment
