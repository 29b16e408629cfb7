// Trajectory → frames → MP4 / PNG sequence, with seeded blinks.
#include "avsi/stimuli/animation.h"

#include <cmath>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/rng.h"
#include "avsi/stimuli/image_io.h"

namespace avsi::stimuli {

std::vector<double> blink_track(std::size_t frames, double fps, const BlinkSettings& s) {
    std::vector<double> track(frames, 0.0);
    if (!s.enabled || frames == 0) return track;
    Rng rng = Rng(s.seed).derive("blinks");
    const double extra = std::max(s.mean_interval_s - s.min_interval_s, 0.01);
    // The first blink may fall anywhere in the first interval.
    double onset = rng.uniform() * s.mean_interval_s;
    const double end = static_cast<double>(frames) / fps;
    while (onset < end) {
        for (std::size_t k = 0; k < frames; ++k) {
            const double t = static_cast<double>(k) / fps - onset;
            double v = 0.0;
            if (t >= 0 && t < s.closing_s) v = t / s.closing_s;
            else if (t >= s.closing_s && t < s.closing_s + s.opening_s) v = 1.0 - (t - s.closing_s) / s.opening_s;
            track[k] = std::max(track[k], v);
        }
        onset += s.min_interval_s - extra * std::log(1.0 - rng.uniform());
    }
    return track;
}

Pose pose_at(const synth::Trajectory& trajectory, std::size_t frame, double blink) {
    Pose pose;
    pose.params = trajectory.frames[frame];
    pose.blink = blink;
    return pose;
}

std::size_t render_video(OffscreenRenderer& renderer, const synth::Trajectory& trajectory, const Audio* audio,
                         const std::filesystem::path& path, const BlinkSettings& blinks, VideoSettings video) {
    if (trajectory.size() == 0) throw InputError(path, "the trajectory has no frames");
    video.fps = trajectory.fps;
    const auto& rs = renderer.settings();
    const auto blink = blink_track(trajectory.size(), trajectory.fps, blinks);
    VideoWriter writer(path, rs.width, rs.height, trajectory.size(), audio, video);
    Image frame;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        // A frame whose pose equals the previous one (held rest at the ends,
        // sustained targets) is the same picture: repeat it without rendering.
        if (k > 0 && trajectory.frames[k] == trajectory.frames[k - 1] && blink[k] == blink[k - 1]) {
            writer.repeat_last();
            continue;
        }
        renderer.render(pose_at(trajectory, k, blink[k]), frame);
        writer.write(frame);
    }
    writer.finish();
    return trajectory.size();
}

std::size_t render_png_sequence(OffscreenRenderer& renderer, const synth::Trajectory& trajectory,
                                const std::filesystem::path& dir, const BlinkSettings& blinks) {
    const auto blink = blink_track(trajectory.size(), trajectory.fps, blinks);
    Image frame;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        renderer.render(pose_at(trajectory, k, blink[k]), frame);
        write_png(dir / fmt::format("frame_{:05}.png", k), frame);
    }
    return trajectory.size();
}

}  // namespace avsi::stimuli
