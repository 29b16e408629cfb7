// The marker fit (learn/marker_fit.h) on the built-in head and its layout
// (protocols/head/markers.json): the closed-form similarity against a known
// transform, and the known answer — markers generated from the head's own
// rig with known parameter tracks, plus noise, head motion, a similarity
// transform and dropouts, give back the tracks within a stated tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include <Eigen/Dense>

#include "avsi/core/error.h"
#include "avsi/learn/marker_fit.h"
#include "avsi/stimuli/head.h"
#include "avsi/stimuli/marker_layout.h"
#include "synthetic_markers.h"

using namespace avsi;
using namespace avsi::learn;

namespace {

const synth::MarkerModel& builtin_model() {
    static const stimuli::Head head = stimuli::load_default_head();
    static const synth::MarkerModel model = stimuli::load_marker_model(head, stimuli::default_marker_layout());
    return model;
}

}  // namespace

TEST(MarkerLayout, BuiltInHeadHasTheStudys30And5Markers) {
    const auto& model = builtin_model();
    std::size_t reference = 0, strategic = 0;
    for (const auto& m : model.markers) {
        reference += m.reference ? 1 : 0;
        strategic += m.orientation ? 1 : 0;
    }
    EXPECT_EQ(model.markers.size() - reference, 30u);
    EXPECT_EQ(reference, 5u);
    EXPECT_GE(strategic, 3u);
    // The rig moves the lip markers: jaw opening lowers the lower lip's midline.
    std::vector<double> rest, open;
    model.pose(synth::Frame{}, rest);
    synth::Frame y{};
    y[synth::index(synth::Param::JawRotation)] = 1.0;
    model.pose(y, open);
    const auto& ll = model.markers[model.marker("LL_C")];
    EXPECT_LT(open[3 * ll.points[0] + 1], rest[3 * ll.points[0] + 1] - 8.0);
    // Posing the two sides apart is the rig's pose when one side is zero.
    synth::Frame y2{}, positive{}, negative{};
    for (std::size_t j = 0; j < synth::param_count; ++j) {
        y2[j] = (j % 2 ? -0.4 : 0.6) * (j % 3 ? 1 : 0.5);
        positive[j] = std::max(y2[j], 0.0);
        negative[j] = std::min(y2[j], 0.0);
    }
    std::vector<double> a, b;
    model.pose(y2, a);
    model.pose_sides(positive, negative, b);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-4) << i;
    EXPECT_TRUE(model.two_sided[synth::index(synth::Param::LowerLipRetraction)]);
    EXPECT_FALSE(model.two_sided[synth::index(synth::Param::JawThrust)]);
}

TEST(MarkerFit, SimilarityRecoversAKnownTransform) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    const Eigen::Vector3d t(10, -20, 30);
    const double s = 1.3;
    std::vector<double> from, to;
    for (int i = 0; i < 6; ++i) {
        const Eigen::Vector3d x(std::sin(i), std::cos(2.0 * i) * 3, i * 0.5);
        const Eigen::Vector3d y = s * R * x + t;
        from.insert(from.end(), {x(0), x(1), x(2)});
        to.insert(to.end(), {y(0), y(1), y(2)});
    }
    const Similarity sim = fit_similarity(from, to, true);
    EXPECT_NEAR(sim.scale, s, 1e-12);
    for (int r = 0; r < 3; ++r) {
        EXPECT_NEAR(sim.translation[r], t(r), 1e-10);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(sim.rotation[3 * r + c], R(r, c), 1e-12);
    }
    EXPECT_NEAR(fit_similarity(from, to, false).scale, 1.0, 0.0);
}

namespace {

// Fits a synthetic recording (360 frames, seed 43) whose frames 100–109 keep
// only two spectacle markers; returns each parameter's RMS and largest
// error over the fitted frames.
struct Recovery {
    std::array<double, synth::param_count> rms{}, worst{};
    MarkerFitResult fit;
};

Recovery recover(double noise_mm) {
    test::SyntheticMarkerSpec spec;
    spec.frames = 360;
    spec.noise_mm = noise_mm;
    std::vector<synth::Frame> truth;
    MarkerRecording rec = test::synthetic_recording(builtin_model(), spec, truth);
    for (std::size_t f = 100; f < 110; ++f)
        for (const char* name : {"REF_L", "REF_R", "REF_TL"})
            std::fill(rec.point(f, rec.marker(name)), rec.point(f, rec.marker(name)) + 3, std::nan(""));
    MarkerFitSettings settings;
    settings.chunk_frames = 120;
    Recovery out;
    out.fit = fit_markers(rec, builtin_model(), settings, "synthetic");
    std::size_t fitted = 0;
    for (std::size_t f = 0; f < rec.frames; ++f) {
        if (!std::isfinite(out.fit.track.frames[f][0])) continue;
        ++fitted;
        for (std::size_t j = 0; j < synth::param_count; ++j) {
            const double e = std::abs(out.fit.track.frames[f][j] - truth[f][j]);
            out.worst[j] = std::max(out.worst[j], e);
            out.rms[j] += e * e;
        }
    }
    for (auto& r : out.rms) r = std::sqrt(r / double(std::max<std::size_t>(fitted, 1)));
    return out;
}

}  // namespace

// Without noise the pipeline (head motion out, orientation, virtual markers,
// shape fit) gives the tracks back to 0.03 units in every frame.
TEST(MarkerFit, RecoversKnownTracksExactlyWithoutNoise) {
    const Recovery r = recover(0.0);
    EXPECT_EQ(r.fit.reference_frame, 0u);
    EXPECT_EQ(r.fit.markers.size(), 30u);
    EXPECT_EQ(r.fit.frames_unplaced, 10u);
    for (std::size_t f = 100; f < 110; ++f) EXPECT_TRUE(std::isnan(r.fit.track.frames[f][0])) << f;
    EXPECT_NEAR(r.fit.orientation.scale, 1.08, 1e-6);
    for (std::size_t j = 0; j < synth::param_count; ++j) EXPECT_LT(r.worst[j], 0.03) << synth::params()[j].name;
}

// With 0.1 mm of marker noise, the tolerance per parameter (RMS error over
// the frames, normalised units; each range is 1.1–2 units wide) follows how
// well the 30 markers see it: the weakest direction of the rig at the
// markers (jaw thrust against lower-lip retraction) moves them by 1.3 mm
// per unit in all, so those two get the widest tolerance.
TEST(MarkerFit, RecoversKnownTracksThroughNoiseHeadMotionAndSimilarity) {
    SCOPED_TRACE("seed 43, noise 0.1 mm");
    const Recovery r = recover(0.1);
    const std::array<double, synth::param_count> tolerance = {0.06, 0.1, 0.06, 0.06, 0.15,
                                                              0.06, 0.1, 0.1,  0.15, 0.06};
    for (std::size_t j = 0; j < synth::param_count; ++j) {
        EXPECT_LT(r.rms[j], tolerance[j]) << synth::params()[j].name;
        EXPECT_LT(r.worst[j], 0.5) << synth::params()[j].name;
    }
    // Dropouts are counted per marker, and the residual stays near the noise.
    std::size_t dropouts = 0;
    for (auto d : r.fit.dropouts) dropouts += d;
    EXPECT_GT(dropouts, 0u);
    double sq = 0;
    std::size_t n = 0;
    for (double v : r.fit.residual_mm)
        if (std::isfinite(v)) sq += v * v, ++n;
    EXPECT_LT(std::sqrt(sq / double(n)), 0.6);
}

TEST(MarkerFit, MissingStrategicMarkersAreRefused) {
    test::SyntheticMarkerSpec spec;
    spec.frames = 5;
    std::vector<synth::Frame> truth;
    MarkerRecording rec = test::synthetic_recording(builtin_model(), spec, truth);
    for (auto& l : rec.labels)
        if (l.rfind("CORNER", 0) == 0 || l.rfind("BROW", 0) == 0 || l == "CHIN_C") l = "X" + l;
    try {
        fit_markers(rec, builtin_model(), {}, "rec.c3d");
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("rec.c3d: error: markers: the orientation fit needs 3 strategic markers"),
                  std::string::npos)
            << e.what();
    }
}
