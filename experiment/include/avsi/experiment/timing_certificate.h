// A timing certificate per online participant, from the per-trial browser
// timing that `avsi import-web` stores: the distribution of the audio-video
// offset over every frame shown, dropped and repeated frames, the refresh
// rate, the AudioContext's reported output latency, and a verdict against
// stated tolerances (ITU-R BT.1359-1's detectability thresholds: sound ahead
// of the picture by more than 45 ms, or behind it by more than 125 ms; a
// share of dropped frames).
//
// The offsets are the browser's own estimate (requestVideoFrameCallback's
// expected display times, the media clock and the AudioContext's reported
// output path), not a measurement at the screen and the ear: online there is
// no photodiode or microphone, so a device that misreports its latency (many
// Bluetooth headphones) passes unseen. docs/online-study.md says what the
// certificate can and cannot tell.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "avsi/experiment/store.h"

namespace avsi::experiment {

struct TimingTolerance {
    double audio_lead_ms = 45.0;      // sound ahead of the picture (offset > +this) is detectable
    double audio_lag_ms = 125.0;      // sound behind the picture (offset < -this) is detectable
    double max_outside_share = 0.05;  // share of frames shown allowed outside [-audio_lag_ms, +audio_lead_ms]
    double max_dropped_share = 0.05;  // share of the clips' frames allowed never shown
};

enum class TimingVerdict { Pass, Fail, Unknown };
std::string to_string(TimingVerdict verdict);

struct TimingCertificate {
    int subject = 0;
    int trials = 0;                // presentations with browser timing
    int frames_total = 0;          // frames in the clips presented
    int frames_shown = 0;
    int dropped_frames = 0;        // never shown
    int repeated_frames = 0;       // shown twice
    double dropped_share = 0.0;    // dropped / total
    int offset_frames = 0;         // frames with an A/V offset (requestVideoFrameCallback)
    // The A/V offset over the frames shown, ms; positive: video late, the sound ahead.
    double offset_min_ms = 0.0;
    double offset_p5_ms = 0.0;
    double offset_median_ms = 0.0;
    double offset_mean_ms = 0.0;
    double offset_p95_ms = 0.0;
    double offset_max_ms = 0.0;
    int audio_leading_frames = 0;  // offset > tolerance.audio_lead_ms
    int audio_lagging_frames = 0;  // offset < -tolerance.audio_lag_ms
    double outside_share = 0.0;    // (leading + lagging) / offset_frames
    double refresh_hz = 0.0;       // median over the trials
    std::optional<double> output_latency_ms;  // median AudioContext.outputLatency where the browser reported one (> 0)
    std::optional<double> audio_path_ms;      // median output path the offsets used
    TimingVerdict verdict = TimingVerdict::Unknown;
    std::vector<std::string> reasons;  // why not Pass
};

// One certificate per subject with online (browser-timed) presentations.
std::vector<TimingCertificate> timing_certificates(const Store& store, const TimingTolerance& tolerance = {});

// The certificates as CSV (one row per subject, the tolerances in columns).
std::string timing_certificate_csv(const std::vector<TimingCertificate>& certificates, const TimingTolerance& tolerance);

// One line for a log: "subject 1: PASS — A/V offset median -23.1 ms (5–95 % -40.2 … -8.0), …".
std::string describe(const TimingCertificate& certificate);

}  // namespace avsi::experiment
