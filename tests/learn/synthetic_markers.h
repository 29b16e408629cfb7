// A synthetic optical recording from a head's own rig, for the marker fit's
// known-answer test and its benchmark: known parameter tracks (smooth, within
// every parameter's range, frame 0 the rest pose), each face marker at its
// layout surface point on the posed head, the reference markers at their
// spectacle-frame points; then head motion (a rotation of up to
// `head_turn_deg` about a slowly wandering axis and a translation of up to
// `head_shift_mm`), the lab's similarity transform (scale, a 90° turn so the
// lab's z is up, an offset), Gaussian noise and random dropouts.
#pragma once

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Dense>

#include "avsi/learn/markers.h"
#include "avsi/synth/marker_model.h"
#include "avsi/synth/parameters.h"

namespace avsi::test {

struct SyntheticMarkerSpec {
    std::size_t frames = 600;
    double rate_hz = 60.0;
    double noise_mm = 0.1;           // sd per coordinate
    double dropout_fraction = 0.03;  // of face marker-frames
    double head_turn_deg = 8.0;
    double head_shift_mm = 15.0;
    double lab_scale = 1.0 / 1.08;   // the speaker's face against the model's
    unsigned seed = 43;
};

// The true parameter frame k (normalised units).
inline synth::Frame synthetic_params(std::size_t k, double rate_hz) {
    synth::Frame y{};
    const double t = double(k) / rate_hz;
    for (std::size_t j = 0; j < synth::param_count; ++j) {
        const auto& info = synth::params()[j];
        const double f = 0.7 + 0.37 * double(j);  // Hz, different per parameter
        const double s = std::sin(2 * std::numbers::pi * f * t + 0.5 * double(j)) - std::sin(0.5 * double(j));
        // s in [-2, 2]; reach 70 % of each side of the range.
        y[j] = s > 0 ? 0.35 * info.max * s : -0.35 * info.min * s;
    }
    return y;
}

inline learn::MarkerRecording synthetic_recording(const synth::MarkerModel& model, const SyntheticMarkerSpec& spec,
                                                  std::vector<synth::Frame>& truth) {
    std::mt19937 rng(spec.seed);
    std::normal_distribution<double> noise(0.0, spec.noise_mm);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    learn::MarkerRecording rec;
    rec.rate_hz = spec.rate_hz;
    rec.frames = spec.frames;
    for (const auto& m : model.markers) rec.labels.push_back(m.name);
    rec.xyz.assign(spec.frames * rec.labels.size() * 3, std::numeric_limits<double>::quiet_NaN());
    const Eigen::Matrix3d lab = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
    const Eigen::Vector3d lab_offset(512.0, -230.0, 1350.0);
    truth.clear();
    std::vector<double> xyz;
    for (std::size_t f = 0; f < spec.frames; ++f) {
        const synth::Frame y = f == 0 ? synth::Frame{} : synthetic_params(f, spec.rate_hz);
        truth.push_back(y);
        model.pose(y, xyz);
        const double t = double(f) / spec.rate_hz;
        const Eigen::Vector3d axis = Eigen::Vector3d(std::sin(0.3 * t), 1.0, 0.4 * std::cos(0.2 * t)).normalized();
        const Eigen::Matrix3d turn =
            Eigen::AngleAxisd(spec.head_turn_deg * std::numbers::pi / 180 * std::sin(0.9 * t), axis).toRotationMatrix();
        const Eigen::Vector3d shift = spec.head_shift_mm * Eigen::Vector3d(std::sin(0.5 * t), std::sin(0.7 * t), std::cos(0.3 * t));
        for (std::size_t m = 0; m < model.markers.size(); ++m) {
            const auto& mm = model.markers[m];
            Eigen::Vector3d p = Eigen::Vector3d::Zero();
            if (mm.reference) {
                p = Eigen::Vector3d(mm.frame_point[0], mm.frame_point[1], mm.frame_point[2]);
            } else {
                for (int k = 0; k < 3; ++k)
                    p += mm.weights[k] * Eigen::Vector3d(xyz[3 * mm.points[k]], xyz[3 * mm.points[k] + 1], xyz[3 * mm.points[k] + 2]);
                if (f > 0 && uniform(rng) < spec.dropout_fraction) continue;
            }
            const Eigen::Vector3d d = spec.lab_scale * (lab * (turn * p + shift)) + lab_offset;
            double* out = rec.point(f, m);
            for (int k = 0; k < 3; ++k) out[k] = d(k) + noise(rng);
        }
    }
    return rec;
}

}  // namespace avsi::test
