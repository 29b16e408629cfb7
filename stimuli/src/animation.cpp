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

std::vector<double> tongue_tip_track(const PhoneSequence& phones, std::size_t frames, double fps, double ramp_s) {
    std::vector<double> track(frames, 0.0);
    for (const auto& ph : phones) {
        const std::string& s = ph.symbol;
        if (s != "TH" && s != "DH" && s != "T" && s != "D" && s != "N" && s != "L") continue;
        for (std::size_t k = 0; k < frames; ++k) {
            const double t = static_cast<double>(k) / fps;
            double v = 0.0;
            if (t >= ph.start_s && t <= ph.end_s) v = 1.0;
            else if (t < ph.start_s && t > ph.start_s - ramp_s) v = 0.5 - 0.5 * std::cos(M_PI * (t - ph.start_s + ramp_s) / ramp_s);
            else if (t > ph.end_s && t < ph.end_s + ramp_s) v = 0.5 + 0.5 * std::cos(M_PI * (t - ph.end_s) / ramp_s);
            track[k] = std::max(track[k], v);
        }
    }
    return track;
}

Pose pose_at(const synth::Trajectory& trajectory, std::size_t frame, double blink, double tongue_tip) {
    Pose pose;
    pose.params = trajectory.frames[frame];
    pose.blink = blink;
    pose.tongue_tip = tongue_tip;
    return pose;
}

std::size_t render_video(OffscreenRenderer& renderer, const synth::Trajectory& trajectory, const Audio* audio,
                         const std::filesystem::path& path, const BlinkSettings& blinks, VideoSettings video,
                         const PhoneSequence* phones) {
    if (trajectory.size() == 0) throw InputError(path, "the trajectory has no frames");
    video.fps = trajectory.fps;
    const auto& rs = renderer.settings();
    const auto blink = blink_track(trajectory.size(), trajectory.fps, blinks);
    const auto tongue = phones ? tongue_tip_track(*phones, trajectory.size(), trajectory.fps)
                               : std::vector<double>(trajectory.size(), 0.0);
    VideoWriter writer(path, rs.width, rs.height, trajectory.size(), audio, video);
    Image frame;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        // A frame whose pose equals the previous one (held rest at the ends,
        // sustained targets) is the same picture: repeat it without rendering.
        if (k > 0 && trajectory.frames[k] == trajectory.frames[k - 1] && blink[k] == blink[k - 1] &&
            tongue[k] == tongue[k - 1]) {
            writer.repeat_last();
            continue;
        }
        renderer.render(pose_at(trajectory, k, blink[k], tongue[k]), frame);
        writer.write(frame);
    }
    writer.finish();
    return trajectory.size();
}

namespace {
bool same_pose(const Pose& a, const Pose& b) {
    for (std::size_t c = 0; c < channel_count; ++c)
        if (a.channel(c) != b.channel(c)) return false;
    return a.head_rotation == b.head_rotation;
}
}  // namespace

std::size_t render_pose_video(OffscreenRenderer& renderer, const std::vector<Pose>& poses, double fps,
                              const Audio* audio, const std::filesystem::path& path, VideoSettings video) {
    if (poses.empty()) throw InputError(path, "the animation has no frames");
    video.fps = fps;
    const auto& rs = renderer.settings();
    VideoWriter writer(path, rs.width, rs.height, poses.size(), audio, video);
    Image frame;
    for (std::size_t k = 0; k < poses.size(); ++k) {
        if (k > 0 && same_pose(poses[k], poses[k - 1])) {
            writer.repeat_last();
            continue;
        }
        renderer.render(poses[k], frame);
        writer.write(frame);
    }
    writer.finish();
    return poses.size();
}

std::size_t render_pose_png_sequence(OffscreenRenderer& renderer, const std::vector<Pose>& poses,
                                     const std::filesystem::path& dir) {
    Image frame;
    for (std::size_t k = 0; k < poses.size(); ++k) {
        renderer.render(poses[k], frame);
        write_png(dir / fmt::format("frame_{:05}.png", k), frame);
    }
    return poses.size();
}

std::size_t render_png_sequence(OffscreenRenderer& renderer, const synth::Trajectory& trajectory,
                                const std::filesystem::path& dir, const BlinkSettings& blinks,
                                const PhoneSequence* phones) {
    const auto blink = blink_track(trajectory.size(), trajectory.fps, blinks);
    const auto tongue = phones ? tongue_tip_track(*phones, trajectory.size(), trajectory.fps)
                               : std::vector<double>(trajectory.size(), 0.0);
    Image frame;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        renderer.render(pose_at(trajectory, k, blink[k], tongue[k]), frame);
        write_png(dir / fmt::format("frame_{:05}.png", k), frame);
    }
    return trajectory.size();
}

}  // namespace avsi::stimuli
