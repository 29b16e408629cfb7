// Articulatory parameter trajectories: frames × 10 parameters at a frame rate,
// with CSV I/O (`time_s,<param>…`). Frame k is at time k / fps.
#pragma once

#include <array>
#include <filesystem>
#include <vector>

#include "avsi/synth/parameters.h"

namespace avsi::synth {

using Frame = std::array<double, param_count>;

struct Trajectory {
    double fps = 60.0;
    std::vector<Frame> frames;

    std::size_t size() const { return frames.size(); }
    double time_s(std::size_t frame) const { return static_cast<double>(frame) / fps; }
    double duration_s() const { return static_cast<double>(frames.size()) / fps; }
    double value(std::size_t frame, Param p) const { return frames[frame][index(p)]; }
};

// The number of frames for an utterance of `duration_s` at `fps`: frames at
// k / fps for k = 0 … ceil(duration_s · fps − 1e-9) − 1, so every frame starts
// inside the utterance and the last one covers its end.
std::size_t frame_count(double duration_s, double fps);

// Frames where parameters leave their documented range (parameters.h).
struct RangeReport {
    std::array<std::size_t, param_count> frames_outside{};  // per parameter
    std::array<double, param_count> worst{};                // the value furthest outside
    std::array<std::size_t, param_count> worst_frame{};
    bool any() const;
};
// Counts the values outside [min, max] of each parameter; with `clamp`, also
// limits them to the range.
RangeReport check_ranges(Trajectory& trajectory, bool clamp);

// CSV with a header `time_s,jaw_rotation,…`. Reading accepts the columns in
// any order, requires all 10 and a constant frame step; errors name file:line.
Trajectory read_trajectory_csv(const std::filesystem::path& path);
void write_trajectory_csv(const std::filesystem::path& path, const Trajectory& trajectory);

}  // namespace avsi::synth
