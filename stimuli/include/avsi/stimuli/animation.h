// Animating the head from a trajectory: one rendered frame per trajectory
// frame, with seeded eye blinks, written as an MP4 (muxed with audio) or a
// PNG sequence.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/phones.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/stimuli/video.h"
#include "avsi/synth/trajectory.h"

namespace avsi::stimuli {

// Blinks at random intervals (a shifted exponential), each a quick close and
// a slower reopening, from a seeded RNG so a stimulus is reproducible.
struct BlinkSettings {
    bool enabled = true;
    std::uint64_t seed = 1;
    double mean_interval_s = 3.5;   // mean time between blink onsets
    double min_interval_s = 1.2;
    double closing_s = 0.07;
    double opening_s = 0.15;
};

// Eyelid closure (0 open … 1 closed) at each of `frames` frames at `fps`.
std::vector<double> blink_track(std::size_t frames, double fps, const BlinkSettings& settings);

// The tongue tip (0 … 1) at each of `frames` frames at `fps`: the rule
// layer of the tongue, which the 10 parameters do not carry. The tip rises
// to the teeth and alveolar ridge through each dental or alveolar consonant
// (/θ ð t d n l/: TH DH T D N L), fully from the segment's start to its end,
// rising and falling over `ramp_s` either side (raised cosine); 0 elsewhere.
// The jaw and lips decide whether it shows.
std::vector<double> tongue_tip_track(const PhoneSequence& phones, std::size_t frames, double fps, double ramp_s = 0.06);

// The pose of frame k of a trajectory with a blink and tongue-tip value.
Pose pose_at(const synth::Trajectory& trajectory, std::size_t frame, double blink, double tongue_tip = 0.0);

// Renders every trajectory frame and writes an MP4 at the trajectory's frame
// rate, muxed with `audio` (nullptr: silent). With `phones` the tongue tip
// follows them (tongue_tip_track). Returns the frame count.
std::size_t render_video(OffscreenRenderer& renderer, const synth::Trajectory& trajectory, const Audio* audio,
                         const std::filesystem::path& path, const BlinkSettings& blinks = {},
                         VideoSettings video = {}, const PhoneSequence* phones = nullptr);

// Renders one frame per pose (an animation's poses, layers.h) and writes an
// MP4 at `fps`, muxed with `audio` (nullptr: silent). Returns the frame count.
std::size_t render_pose_video(OffscreenRenderer& renderer, const std::vector<Pose>& poses, double fps,
                              const Audio* audio, const std::filesystem::path& path, VideoSettings video = {});
// Renders one PNG per pose as DIR/frame_00000.png …
std::size_t render_pose_png_sequence(OffscreenRenderer& renderer, const std::vector<Pose>& poses,
                                     const std::filesystem::path& dir);

// Renders every frame as DIR/frame_00000.png …
std::size_t render_png_sequence(OffscreenRenderer& renderer, const synth::Trajectory& trajectory,
                                const std::filesystem::path& dir, const BlinkSettings& blinks = {},
                                const PhoneSequence* phones = nullptr);

}  // namespace avsi::stimuli
