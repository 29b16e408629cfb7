// Animation layers (stimuli/layers.h; Charisma paper §3): the blend rules
// against hand-computed poses, the FAP player on the head's geometry,
// expressions + speech keeping every bilabial closure on running speech,
// the blink and gaze layers' statistics over 10 minutes, the protocol's
// [condition.layers] and the builder's manifest record.
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>

#include <fmt/format.h>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/protocol.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/layers.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/synth/control_model.h"
#include "support/heads.h"
#include "support/layers_protocol.h"
#include "support/sentences.h"
#include "support/temp_dir.h"

namespace avsi::stimuli {
namespace {

using test::default_head;

// A layer of `frames` frames that sets channel c to v in every frame.
Layer constant(const std::string& name, LayerSet set, std::size_t c, double v, std::size_t frames = 1) {
    Layer l;
    l.name = name;
    l.set = set;
    l.frames.resize(frames);
    for (auto& f : l.frames) f.set_channel(c, v);
    return l;
}

Layer rotation(const std::string& name, LayerSet set, const glm::quat& q) {
    Layer l;
    l.name = name;
    l.set = set;
    l.frames.resize(1);
    l.frames[0].set_rotation(q);
    return l;
}

double yaw_deg(const glm::quat& q) {
    // The rotation's angle about +y (the tests rotate about y only).
    const glm::vec3 axis = glm::axis(q);
    return glm::degrees(glm::angle(q)) * (axis.y < 0 ? -1.0 : 1.0);
}

glm::quat yaw(double deg) { return glm::angleAxis(static_cast<float>(glm::radians(deg)), glm::vec3(0, 1, 0)); }

// ---- Blend rules against hand-computed poses --------------------------------

TEST(LayerBlend, ModulesBlendAtHalfAndOverrideStreamLayers) {
    const auto c = brow_inner_raise_channel;
    // Two modules at their default weights: LERP at 0.5.
    EXPECT_NEAR(blend_frame({constant("a", LayerSet::Module, c, 0.8), constant("b", LayerSet::Module, c, 0.2)}, 0).brow_inner_raise,
                0.5, 1e-12);
    // A stream layer alone plays in direct mode; beside a module it yields.
    EXPECT_NEAR(blend_frame({constant("s", LayerSet::Stream, c, 0.9)}, 0).brow_inner_raise, 0.9, 1e-12);
    EXPECT_NEAR(blend_frame({constant("s", LayerSet::Stream, c, 0.9), constant("m", LayerSet::Module, c, 0.3)}, 0).brow_inner_raise,
                0.3, 1e-12);
    // The animator's weights: stream 0.5 beside a module at 1 → (0.5·0.9 + 1·0.3) / 1.5.
    auto stream = constant("s", LayerSet::Stream, c, 0.9);
    stream.weight = 0.5;
    EXPECT_NEAR(blend_frame({stream, constant("m", LayerSet::Module, c, 0.3)}, 0).brow_inner_raise, (0.45 + 0.3) / 1.5, 1e-12);
    // Weights summing below 1 blend toward rest: a lone layer at 0.4 shows 40 %.
    auto lone = constant("m", LayerSet::Module, c, 0.8);
    lone.weight = 0.4;
    EXPECT_NEAR(blend_frame({lone}, 0).brow_inner_raise, 0.32, 1e-12);
    // A group weight overrides the layer weight for that group only.
    Layer both = constant("e", LayerSet::Module, c, 0.8);
    both.frames[0].set_channel(cheek_raise_channel, 0.6);
    both.weight = 1.0;
    both.group_weights[static_cast<std::size_t>(FeatureGroup::Eyebrows)] = 0.25;
    const Pose p = blend_frame({both}, 0);
    EXPECT_NEAR(p.brow_inner_raise, 0.2, 1e-12);
    EXPECT_NEAR(p.cheek_raise, 0.6, 1e-12);
    // A channel no layer sets stays at rest; layers that do not set a
    // channel do not dilute it (the blink beside a gaze layer).
    Layer gaze = constant("gaze", LayerSet::Module, gaze_left_channel, 0.3);
    const Pose q = blend_frame({gaze, constant("blink", LayerSet::Module, blink_channel, 1.0)}, 0);
    EXPECT_EQ(q.blink, 1.0);
    EXPECT_EQ(q.gaze_left, 0.3);
    EXPECT_EQ(q.gaze_up, 0.0);
    EXPECT_EQ(q.cheek_raise, 0.0);
}

TEST(LayerBlend, SpeechOwnsTheMouthUnlessTheAnimatorSharesIt) {
    const auto jaw = index(synth::Param::JawRotation);
    Layer speech = constant("speech", LayerSet::Module, jaw, -0.1);
    speech.is_speech = true;
    speech.frames[0].set_channel(tongue_tip_channel, 0.7);
    Layer expression = constant("expression", LayerSet::Module, jaw, 0.5);
    expression.frames[0].set_channel(tongue_tip_channel, 0.0);
    expression.frames[0].set_channel(brow_outer_raise_channel, 0.6);
    expression.weight = 1.0;
    Layer stream = constant("fap", LayerSet::Stream, index(synth::Param::LowerLipDepression), 0.8);
    stream.weight = 1.0;
    const Pose owned = blend_frame({speech, expression, stream}, 0, true);
    EXPECT_EQ(owned.params[jaw], -0.1);  // exactly the speech layer's value
    EXPECT_EQ(owned.tongue_tip, 0.7);
    EXPECT_EQ(owned.params[index(synth::Param::LowerLipDepression)], 0.0);  // speech does not set it: rest
    EXPECT_NEAR(owned.brow_outer_raise, 0.6, 1e-12);                         // outside the mouth the expression shows
    const Pose shared = blend_frame({speech, expression, stream}, 0, false);
    EXPECT_NEAR(shared.params[jaw], 0.2, 1e-12);  // 0.5 LERP of −0.1 and 0.5
    EXPECT_NEAR(shared.tongue_tip, 0.35, 1e-12);
    EXPECT_NEAR(shared.params[index(synth::Param::LowerLipDepression)], 0.8, 1e-12);
}

TEST(LayerBlend, HeadRotationsBlendBySlerp) {
    // Two modules about the same axis at default weights: the mean angle.
    EXPECT_NEAR(yaw_deg(blend_frame({rotation("a", LayerSet::Module, yaw(10)), rotation("b", LayerSet::Module, yaw(30))}, 0).head_rotation),
                20.0, 1e-3);
    // Weights 1 and 3: 10 + (30 − 10)·3/4.
    Layer a = rotation("a", LayerSet::Module, yaw(10)), b = rotation("b", LayerSet::Module, yaw(30));
    a.weight = 1.0;
    b.weight = 3.0;
    EXPECT_NEAR(yaw_deg(blend_frame({a, b}, 0).head_rotation), 25.0, 1e-3);
    // A lone layer at 0.5: half way from the identity.
    Layer half = rotation("h", LayerSet::Module, yaw(40));
    half.weight = 0.5;
    EXPECT_NEAR(yaw_deg(blend_frame({half}, 0).head_rotation), 20.0, 1e-3);
    // A stream layer yields to a module; alone it plays.
    EXPECT_NEAR(yaw_deg(blend_frame({rotation("s", LayerSet::Stream, yaw(30)), rotation("m", LayerSet::Module, yaw(-10))}, 0).head_rotation),
                -10.0, 1e-3);
    EXPECT_NEAR(yaw_deg(blend_frame({rotation("s", LayerSet::Stream, yaw(30))}, 0).head_rotation), 30.0, 1e-3);
    // SLERP, not a component LERP: a 90° and a −90° turn about different
    // axes blend to a unit quaternion at equal angles from each.
    const glm::quat x90 = glm::angleAxis(glm::radians(90.0f), glm::vec3(1, 0, 0));
    const glm::quat q = blend_frame({rotation("a", LayerSet::Module, x90), rotation("b", LayerSet::Module, yaw(90))}, 0).head_rotation;
    EXPECT_NEAR(glm::length(q), 1.0, 1e-6);
    EXPECT_NEAR(glm::degrees(glm::angle(glm::inverse(q) * x90)), glm::degrees(glm::angle(glm::inverse(q) * yaw(90))), 1e-3);
    // No layer rotates: the identity, exactly (the renderer's cached path).
    EXPECT_TRUE(blend_frame({constant("a", LayerSet::Module, blink_channel, 1.0)}, 0).head_at_rest());
}

TEST(LayerBlend, SpeechOnlyStackGivesTheRenderersPosesExactly) {
    // The default stack (speech + blinks) gives the poses render_video
    // makes, value for value: speech-only stimuli are unchanged.
    const auto model = synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json");
    const PhoneSequence phones = synthesize_speech("Bob wore a blue wool coat.").phones;
    const auto trajectory = model->synthesize(phones, 30.0);
    LayerSeeds seeds;
    seeds.blink = 99;
    const Animation a = animate(default_head(), trajectory, &phones, LayerSettings::speech_only(), seeds);
    BlinkSettings blinks;
    blinks.seed = 99;
    const auto blink = blink_track(trajectory.size(), 30.0, blinks);
    const auto tongue = tongue_tip_track(phones, trajectory.size(), 30.0);
    ASSERT_EQ(a.poses.size(), trajectory.size());
    std::size_t blinking = 0;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        const Pose ref = pose_at(trajectory, k, blink[k], tongue[k]);
        for (std::size_t c = 0; c < channel_count; ++c) ASSERT_EQ(a.poses[k].channel(c), ref.channel(c)) << k << " " << c;
        EXPECT_TRUE(a.poses[k].head_at_rest());
        blinking += blink[k] > 0;
    }
    EXPECT_GT(blinking, 0u);
    EXPECT_TRUE(a.warnings.empty());
}

// ---- The FAP player on the head's geometry ----------------------------------

double largest_displacement(const Pose& pose) {
    std::vector<glm::vec3> posed;
    pose_positions(default_head(), pose, posed);
    double d = 0.0;
    for (std::size_t i = 0; i < posed.size(); ++i) d = std::max(d, double(glm::length(posed[i] - default_head().mesh.positions[i])));
    return d;
}

TEST(FapPlayer, BrowCheekAndHeadFapsMoveTheHeadByTheirFapu) {
    const FapPlayer player(default_head());
    const Fapu f = fapu(default_head());
    synth::FapFrame fap;
    auto set = [&](int n, double v) {
        fap.mask[static_cast<std::size_t>(n - 1)] = true;
        fap.values[static_cast<std::size_t>(n - 1)] = v;
    };
    set(31, 200);
    set(32, 200);
    set(41, 150);
    set(42, 150);
    set(49, 10000);  // head yaw 0.1 rad
    const LayerFrame frame = player.frame(fap);
    ASSERT_TRUE(frame.set[brow_inner_raise_channel]);
    ASSERT_TRUE(frame.set[cheek_raise_channel]);
    EXPECT_FALSE(frame.set[index(synth::Param::JawRotation)]);  // no jaw FAP: the jaw is not held
    EXPECT_FALSE(frame.set[blink_channel]);
    // The brows' largest vertex displacement is the FAP's distance: 200 ENS/1024.
    Pose brows;
    brows.brow_inner_raise = frame.values[brow_inner_raise_channel];
    EXPECT_GT(brows.brow_inner_raise, 0.1);
    EXPECT_NEAR(largest_displacement(brows), 200.0 * f.ens / 1024.0, 0.02 * 200.0 * f.ens / 1024.0);
    Pose cheeks;
    cheeks.cheek_raise = frame.values[cheek_raise_channel];
    EXPECT_NEAR(largest_displacement(cheeks), 150.0 * f.ens / 1024.0, 0.02 * 150.0 * f.ens / 1024.0);
    ASSERT_TRUE(frame.sets_rotation);
    EXPECT_NEAR(glm::angle(frame.rotation), 0.1, 1e-5);
    EXPECT_NEAR(glm::axis(frame.rotation).y, 1.0, 1e-5);
    // Nose FAPs have no channel: reported.
    synth::FapStream stream;
    set(61, 100);
    stream.frames.push_back(fap);
    const auto unplayable = player.unplayable_faps(stream);
    ASSERT_EQ(unplayable.size(), 1u);
    EXPECT_EQ(unplayable[0], "61 stretch_l_nose");
}

TEST(FapPlayer, NamedExpressionsComeFromTheDataFile) {
    const auto names = expression_names(default_expressions_file());
    for (const char* n : {"neutral", "happy", "sad", "surprised"})
        EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
    const FapPlayer player(default_head());
    const LayerFrame surprised = player.frame(named_expression(default_expressions_file(), "surprised"));
    EXPECT_GT(surprised.values[brow_inner_raise_channel], 0.3);
    EXPECT_GT(surprised.values[brow_outer_raise_channel], 0.3);
    EXPECT_TRUE(surprised.set[index(synth::Param::JawRotation)]);  // open_jaw: a mouth FAP (the speech layer owns it)
    const LayerFrame happy = player.frame(named_expression(default_expressions_file(), "happy"));
    EXPECT_GT(happy.values[cheek_raise_channel], 0.3);
    const LayerFrame sad = player.frame(named_expression(default_expressions_file(), "sad"));
    EXPECT_GT(sad.values[brow_inner_raise_channel], 0.3);
    EXPECT_LT(sad.values[brow_outer_raise_channel], 0.0);
    EXPECT_THROW(named_expression(default_expressions_file(), "angry"), InputError);
}

// ---- Expressions + speech keep every bilabial closure ------------------------

using test::utterances;

// The default protocol's model conditions (every model as trained or hand-set).
std::vector<std::pair<std::string, std::shared_ptr<const synth::ControlModel>>> protocol_models() {
    std::vector<std::pair<std::string, std::shared_ptr<const synth::ControlModel>>> out;
    const Protocol protocol = load_protocol(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "beskow2004-en.toml");
    for (const auto& c : protocol.conditions) {
        if (c.face != FaceMode::Model) continue;
        out.push_back({c.name, synth::load_model(c.model)});
    }
    return out;
}

LayerSettings expressive(const std::string& expression, bool owns_mouth = true) {
    LayerSettings s = LayerSettings::speech_only();
    s.configured = true;
    s.speech_owns_mouth = owns_mouth;
    LayerSpec e;
    e.kind = LayerKind::Expression;
    e.source = expression;
    s.layers.push_back(e);
    LayerSpec g;
    g.kind = LayerKind::Gaze;
    s.layers.push_back(g);
    LayerSpec h;
    h.kind = LayerKind::HeadMotion;
    h.source = "idle";
    s.layers.push_back(h);
    return s;
}

TEST(LayersArticulation, HappyAndSurprisedWithSpeechKeepEveryModelsBilabialClosures) {
    ASSERT_GE(utterances().size(), 20u);
    const ArticulationMeter meter(default_head());
    const auto models = protocol_models();
    ASSERT_GE(models.size(), 4u);
    for (const char* expression : {"happy", "surprised"}) {
        const LayerSettings layers = expressive(expression);
        std::size_t bilabials = 0;
        double expression_reach = 0.0;
        for (const auto& [name, model] : models)
            for (const auto& u : utterances()) {
                const auto trajectory = model->synthesize(u.phones, 30.0);
                const Animation a = animate(default_head(), trajectory, &u.phones, layers);
                std::vector<ArticulationMeasures> measures;
                for (const auto& pose : a.poses) measures.push_back(meter.measure(pose));
                const auto layered = check_articulation(u.phones, 30.0, measures);
                const auto plain = check_articulation(u.phones, 30.0, meter.measure(trajectory));
                SCOPED_TRACE(fmt::format("{} on {}: \"{}\"", expression, name, u.text));
                // The layers close what the speech closes and open nothing it closes.
                EXPECT_EQ(layered.bilabials_closed, plain.bilabials_closed);
                EXPECT_EQ(layered.labiodentals_reached, plain.labiodentals_reached);
                for (const auto& p : layered.failures(false)) ADD_FAILURE() << p;
                bilabials += layered.bilabials;
                // The expression shows: the upper face moves by millimetres.
                Pose upper;
                upper.brow_inner_raise = a.poses[0].brow_inner_raise;
                upper.brow_outer_raise = a.poses[0].brow_outer_raise;
                upper.cheek_raise = a.poses[0].cheek_raise;
                expression_reach = std::max(expression_reach, largest_displacement(upper));
            }
        EXPECT_GT(bilabials, 80u * models.size() / 2);
        EXPECT_GT(expression_reach, 3.0) << expression;
    }
}

TEST(LayersArticulation, SharingTheMouthBlendsTheExpressionIntoTheSpeech) {
    // Owned (the default), the mouth is the speech layer's value for value;
    // shared, the expression's mouth FAPs (happy: the lip corners) blend in
    // at 0.5, so the protection is the ownership, not the FAP set.
    const auto model = synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json");
    const auto& u = utterances().front();
    const auto trajectory = model->synthesize(u.phones, 30.0);
    const Animation owned = animate(default_head(), trajectory, &u.phones, expressive("happy", true));
    const Animation shared = animate(default_head(), trajectory, &u.phones, expressive("happy", false));
    const auto stretch = index(synth::Param::MouthCornerStretchLeft);
    std::size_t moved = 0;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        EXPECT_EQ(owned.poses[k].params, trajectory.frames[k]) << k;
        moved += std::abs(shared.poses[k].params[stretch] - trajectory.frames[k][stretch]) > 0.05;
    }
    EXPECT_GT(moved, trajectory.size() * 9 / 10);
    // The surprised jaw, shared, on the rule model (printed: its bilabial
    // targets press the lips, so few open).
    const ArticulationMeter meter(default_head());
    std::size_t open = 0, total = 0;
    for (const auto& v : utterances()) {
        const auto t = model->synthesize(v.phones, 30.0);
        const Animation a = animate(default_head(), t, &v.phones, expressive("surprised", false));
        std::vector<ArticulationMeasures> measures;
        for (const auto& pose : a.poses) measures.push_back(meter.measure(pose));
        const auto s = check_articulation(v.phones, 30.0, measures);
        open += s.bilabials - s.bilabials_closed;
        total += s.bilabials;
    }
    std::printf("surprised with the mouth shared, rule model: %zu of %zu bilabials open\n", open, total);
    EXPECT_GT(total, 80u);
}

// ---- Blink and gaze statistics over 10 minutes ------------------------------

// Kolmogorov-Smirnov statistic of samples against a CDF.
template <typename Cdf>
double ks_statistic(std::vector<double> x, Cdf cdf) {
    std::sort(x.begin(), x.end());
    double d = 0.0;
    const double n = static_cast<double>(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
        const double f = cdf(x[i]);
        d = std::max({d, std::abs(f - static_cast<double>(i) / n), std::abs(static_cast<double>(i + 1) / n - f)});
    }
    return d;
}

TEST(LayerStatistics, BlinksOverTenMinutesMatchTheStatedRateAndDurations) {
    // Stated (layers.h): onset intervals min 1.2 s + exponential (mean 3.5 −
    // 1.2 s), so 17.1 blinks/min; each blink closes in 0.07 s and reopens in 0.15 s.
    const double fps = 200.0, minutes = 10.0;
    const std::size_t frames = static_cast<std::size_t>(minutes * 60.0 * fps);
    const BlinkSettings stated;
    for (std::uint64_t seed : {1u, 2u, 3u, 2004u}) {
        SCOPED_TRACE(fmt::format("seed {}", seed));
        BlinkSettings s;
        s.seed = seed;
        const Layer layer = blink_layer(frames, fps, s);
        std::vector<double> onsets, durations, to_closed;
        for (std::size_t k = 0; k < frames; ++k) {
            const double v = layer.frames[k].values[blink_channel];
            const double prev = k > 0 ? layer.frames[k - 1].values[blink_channel] : 0.0;
            if (v > 0.0 && prev == 0.0) {
                // A blink: measured from the track, frame by frame.
                std::size_t end = k, peak = k;
                while (end < frames && layer.frames[end].values[blink_channel] > 0.0) {
                    if (layer.frames[end].values[blink_channel] > layer.frames[peak].values[blink_channel]) peak = end;
                    ++end;
                }
                onsets.push_back((static_cast<double>(k) - 0.5) / fps);
                durations.push_back(static_cast<double>(end - k + 1) / fps);
                to_closed.push_back(static_cast<double>(peak - k + 1) / fps);
                EXPECT_GT(layer.frames[peak].values[blink_channel], 0.97);  // closes fully
            }
        }
        const double rate = static_cast<double>(onsets.size()) / minutes;
        const double expected_rate = 60.0 / stated.mean_interval_s;
        // ±3 standard errors of a count with the intervals' spread.
        const double extra = stated.mean_interval_s - stated.min_interval_s;
        const double rate_se = expected_rate * (extra / stated.mean_interval_s) / std::sqrt(expected_rate * minutes);
        EXPECT_NEAR(rate, expected_rate, 3.0 * rate_se);
        std::vector<double> intervals;
        for (std::size_t i = 1; i < onsets.size(); ++i) intervals.push_back(onsets[i] - onsets[i - 1]);
        ASSERT_GT(intervals.size(), 100u);
        EXPECT_GE(*std::min_element(intervals.begin(), intervals.end()), stated.min_interval_s - 1.0 / fps);
        const double mean = std::accumulate(intervals.begin(), intervals.end(), 0.0) / double(intervals.size());
        EXPECT_NEAR(mean, stated.mean_interval_s, 3.0 * extra / std::sqrt(double(intervals.size())));
        // The shape: a shifted exponential (KS at the 1 % level).
        const double d = ks_statistic(intervals, [&](double x) {
            return x <= stated.min_interval_s ? 0.0 : 1.0 - std::exp(-(x - stated.min_interval_s) / extra);
        });
        EXPECT_LT(d, 1.63 / std::sqrt(double(intervals.size())));
        for (double du : durations) EXPECT_NEAR(du, stated.closing_s + stated.opening_s, 2.0 / fps);
        for (double c : to_closed) EXPECT_NEAR(c, stated.closing_s, 2.5 / fps);
    }
}

TEST(LayerStatistics, GazeSaccadesOverTenMinutesMatchTheStatedDistributions) {
    // Stated (layers.h): fixations min 0.3 s + exponential (mean 1.2 s in
    // all); landing points round the camera at an exponential eccentricity
    // (mean 2.5°, truncated at 8°; vertical ×0.6), or back to the camera
    // with probability 0.6 when away; durations 21 ms + 2.2 ms/°.
    const double fps = 500.0, seconds = 600.0;
    const std::size_t frames = static_cast<std::size_t>(seconds * fps);
    const GazeSettings stated;
    for (std::uint64_t seed : {1u, 7u, 2004u}) {
        SCOPED_TRACE(fmt::format("seed {}", seed));
        GazeSettings s;
        s.seed = seed;
        const auto track = gaze_track_deg(frames, fps, s);
        // Saccades measured from the track: runs of frames where the gaze moves.
        struct Run {
            std::size_t start, end;  // frames [start, end) differ from their predecessor
        };
        std::vector<Run> runs;
        for (std::size_t k = 1; k < frames; ++k) {
            const bool moving = track[k] != track[k - 1];
            if (moving && (runs.empty() || runs.back().end != k)) runs.push_back({k, k + 1});
            else if (moving) runs.back().end = k + 1;
        }
        ASSERT_GT(runs.size(), 300u);
        std::vector<double> fixations, eccentricities;
        std::size_t returns = 0, from_away = 0;
        for (std::size_t i = 0; i < runs.size(); ++i) {
            const auto& r = runs[i];
            const auto from = track[r.start - 1], to = track[r.end - 1];
            const double amplitude = std::hypot(to[0] - from[0], to[1] - from[1]);
            // The frames inside the saccade and its landing frame: D·fps to D·fps + 2.
            const double duration = static_cast<double>(r.end - r.start) / fps;
            EXPECT_NEAR(duration, 0.021 + 0.0022 * amplitude + 1.0 / fps, 1.0 / fps + 1e-9)
                << "saccade at " << double(r.start) / fps;
            if (i + 1 < runs.size()) fixations.push_back(static_cast<double>(runs[i + 1].start - r.end) / fps);
            const bool away = from[0] != 0.0 || from[1] != 0.0;
            const bool home = to[0] == 0.0 && to[1] == 0.0;
            if (away) ++from_away, returns += home;
            if (!home) eccentricities.push_back(std::hypot(to[0], to[1] / stated.vertical_scale));
        }
        // Fixation durations: shifted exponential, mean 1.2 s, min 0.3 s.
        const double extra = stated.mean_fixation_s - stated.min_fixation_s;
        const double mean_fix = std::accumulate(fixations.begin(), fixations.end(), 0.0) / double(fixations.size());
        EXPECT_NEAR(mean_fix, stated.mean_fixation_s, 3.0 * extra / std::sqrt(double(fixations.size())) + 2.0 / fps);
        EXPECT_GE(*std::min_element(fixations.begin(), fixations.end()), stated.min_fixation_s - 2.0 / fps);
        EXPECT_LT(ks_statistic(fixations,
                               [&](double x) { return x <= stated.min_fixation_s ? 0.0 : 1.0 - std::exp(-(x - stated.min_fixation_s) / extra); }),
                  1.63 / std::sqrt(double(fixations.size())) + 0.01);
        // Returns to the camera.
        const double p = double(returns) / double(from_away);
        EXPECT_NEAR(p, stated.return_probability, 3.0 * std::sqrt(0.24 / double(from_away)));
        // Eccentricity: the truncated exponential's CDF.
        const double mu = stated.mean_amplitude_deg, cap = stated.max_amplitude_deg;
        const double norm = 1.0 - std::exp(-cap / mu);
        EXPECT_LE(*std::max_element(eccentricities.begin(), eccentricities.end()), cap + 1e-9);
        EXPECT_LT(ks_statistic(eccentricities, [&](double x) { return (1.0 - std::exp(-x / mu)) / norm; }),
                  1.63 / std::sqrt(double(eccentricities.size())));
    }
}

// ---- Rendering: head rotation and expressions ---------------------------------

double mean_abs_difference(const Image& a, const Image& b) {
    double d = 0.0;
    for (std::size_t i = 0; i < a.rgb.size(); ++i) d += std::abs(int(a.rgb[i]) - int(b.rgb[i]));
    return d / double(a.rgb.size());
}

TEST(LayersRender, HeadRotationAndExpressionsRenderAndTheRestFrameStaysCached) {
    RenderSettings rs;
    rs.width = 160;
    rs.height = 120;
    OffscreenRenderer renderer(default_head(), rs);
    const Image rest = renderer.render(Pose{});
    Pose turned;
    turned.head_rotation = head_rotation_from_angles(0.0, glm::radians(8.0), 0.0);
    const Image turned_image = renderer.render(turned);
    EXPECT_GT(mean_abs_difference(rest, turned_image), 2.0);
    Pose surprised;
    surprised.brow_inner_raise = 1.0;
    surprised.brow_outer_raise = 1.0;
    const Image brows = renderer.render(surprised);
    EXPECT_GT(mean_abs_difference(rest, brows), 0.05);
    // After those uncached frames the cached rest frame is the same picture.
    const Image again = renderer.render(Pose{});
    EXPECT_EQ(again.rgb, rest.rgb);
    // The rotation is rigid about the neck pivot, which stays put.
    PosedMesh posed;
    pose_head(default_head(), Pose{}, posed);
    PosedMesh rotated = posed;
    apply_head_rotation(default_head(), turned.head_rotation, rotated);
    for (std::size_t i = 0; i < posed.positions.size(); i += 997)
        EXPECT_NEAR(glm::distance(posed.positions[i], default_head().landmarks.neck_pivot),
                    glm::distance(rotated.positions[i], default_head().landmarks.neck_pivot), 1e-3);
    EXPECT_TRUE(default_head().landmarks.has_neck_pivot);
}

TEST(LayersRender, AHeadWithoutTheExpressionChannelsLoadsRendersAndWarns) {
    // A lab's head: the built-in rig without the brow and cheek transforms.
    const auto dir = test::temp_dir("layers_head");
    auto rig = nlohmann::json::parse(read_text_file(default_head_rig()));
    nlohmann::json kept = nlohmann::json::array();
    for (const auto& t : rig["transforms"]) {
        const std::string c = t["channel"];
        if (c != "brow_inner_raise" && c != "brow_outer_raise" && c != "cheek_raise") kept.push_back(t);
    }
    ASSERT_LT(kept.size(), rig["transforms"].size());
    rig["transforms"] = kept;
    rig["landmarks"].erase("neck_pivot");
    rig["texture"] = (default_head_rig().parent_path() / "head.png").string();
    write_text_file(dir / "lab.rig.json", rig.dump());
    const Head lab = load_head(default_head_obj(), dir / "lab.rig.json");
    EXPECT_FALSE(lab.landmarks.has_neck_pivot);
    synth::Trajectory t;
    t.fps = 30.0;
    t.frames.assign(10, synth::Frame{});
    const Animation a = animate(lab, t, nullptr, expressive("surprised"));
    ASSERT_FALSE(a.warnings.empty());
    std::string all;
    for (const auto& w : a.warnings) all += w + "\n";
    EXPECT_NE(all.find("no brow_inner_raise"), std::string::npos) << all;
    RenderSettings rs;
    rs.width = 80;
    rs.height = 60;
    OffscreenRenderer renderer(lab, rs);
    const Image image = renderer.render(a.poses[5]);
    EXPECT_EQ(image.width, 80);
    std::filesystem::remove_all(dir);
}

// ---- Settings: the protocol's [condition.layers] ------------------------------

Protocol protocol_with(const std::string& layers, const std::filesystem::path& path) {
    test::write_layers_protocol(path, "layers-test", layers);
    return load_protocol(path);
}

struct LayersProtocol : ::testing::Test {
    std::filesystem::path dir = test::temp_dir("layers_protocol");
    void TearDown() override { std::filesystem::remove_all(dir); }
    // The problems of the expressive condition's layers, one per line.
    std::string problems_of(const std::string& layers) {
        const Protocol p = protocol_with(layers, dir / "p.toml");
        DiagnosticList problems;
        parse_layer_settings(p.conditions[1].layers, dir, problems);
        try {
            problems.throw_if_any();
        } catch (const InputError& e) {
            return e.what();
        }
        return "";
    }
};

TEST_F(LayersProtocol, ReadsTheLayersTableAndDefaultsToSpeechOnly) {
    write_text_file(dir / "nod.csv", "time_s,w,x,y,z\n0,1,0,0,0\n1,0.9961947,0.0871557,0,0\n");
    const Protocol p = protocol_with(R"([condition.layers]
expression = { name = "happy", weight = 0.8, groups = { cheeks = 1.0 } }
gaze = { mean_fixation_s = 2.0 }
head_motion = { quaternions = "nod.csv" }
)",
                                     dir / "p.toml");
    DiagnosticList problems;
    const LayerSettings plain = parse_layer_settings(p.conditions[0].layers, dir, problems);
    const LayerSettings s = parse_layer_settings(p.conditions[1].layers, dir, problems);
    ASSERT_TRUE(problems.empty());
    EXPECT_FALSE(plain.configured);
    ASSERT_EQ(plain.layers.size(), 1u);
    EXPECT_EQ(plain.layers[0].kind, LayerKind::Blink);
    EXPECT_TRUE(s.configured);
    ASSERT_EQ(s.layers.size(), 4u);  // blink (default on), gaze, head motion, expression
    EXPECT_EQ(s.layers[0].kind, LayerKind::Blink);
    EXPECT_EQ(s.layers[1].kind, LayerKind::Gaze);
    EXPECT_DOUBLE_EQ(s.layers[1].gaze.mean_fixation_s, 2.0);
    EXPECT_EQ(s.layers[2].kind, LayerKind::HeadMotion);
    EXPECT_EQ(s.layers[2].source, "quaternions");
    EXPECT_EQ(s.layers[3].kind, LayerKind::Expression);
    EXPECT_EQ(s.layers[3].source, "happy");
    EXPECT_DOUBLE_EQ(*s.layers[3].weight, 0.8);
    EXPECT_DOUBLE_EQ(*s.layers[3].group_weights[static_cast<std::size_t>(FeatureGroup::Cheeks)], 1.0);
    // The quaternion stream plays: a 10° nod at 1 s, half of it at 0.5 s.
    synth::Trajectory t;
    t.fps = 10.0;
    t.frames.assign(11, synth::Frame{});
    const Animation a = animate(default_head(), t, nullptr, s);
    EXPECT_NEAR(glm::degrees(glm::angle(a.poses[5].head_rotation)), 5.0, 0.01);
    EXPECT_NEAR(glm::degrees(glm::angle(a.poses[10].head_rotation)), 10.0, 0.01);
    const auto record = nlohmann::json::parse(a.record_json);
    ASSERT_EQ(record.size(), 5u);
    EXPECT_EQ(record[3]["sha256"], sha256_file(dir / "nod.csv"));
    EXPECT_EQ(record[4]["name"], "happy");
    // The study's own protocol stays speech-only.
    const Protocol study = load_protocol(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "beskow2004-en.toml");
    for (const auto& c : study.conditions) EXPECT_FALSE(c.layers.present()) << c.name;
}

TEST_F(LayersProtocol, BadSettingsNameTheFileLineAndField) {
    const std::string typo = problems_of("[condition.layers]\nexpression = \"hapy\"\n");
    EXPECT_NE(typo.find("p.toml:13:14: error: "), std::string::npos) << typo;
    EXPECT_NE(typo.find("layers.expression: expected an expression of expressions.json"), std::string::npos) << typo;
    EXPECT_NE(typo.find("did you mean 'happy'"), std::string::npos) << typo;
    const std::string mouth = problems_of("[condition.layers]\nexpression = { name = \"happy\", groups = { jaw = 0.5 } }\n");
    EXPECT_NE(mouth.find("the speech layer owns the mouth groups"), std::string::npos) << mouth;
    const std::string missing = problems_of("[condition.layers]\nfap = \"missing.fap\"\n");
    EXPECT_NE(missing.find("layers.fap: expected a readable file"), std::string::npos) << missing;
    const std::string unknown = problems_of("[condition.layers]\ngaze = { mean_fixation = 2.0 }\n");
    EXPECT_NE(unknown.find("mean_fixation"), std::string::npos) << unknown;
    EXPECT_NE(unknown.find("did you mean"), std::string::npos) << unknown;
    const std::string weight = problems_of("[condition.layers]\ngaze = { weight = 2 }\n");
    EXPECT_NE(weight.find("layers.gaze.weight: expected"), std::string::npos) << weight;
    // A quaternion stream with a bad row: file:line:col at animate time.
    write_text_file(dir / "bad.csv", "time_s,w,x,y,z\n0,1,0,0,0\n0.5,1,0,zero,0\n");
    const Protocol p = protocol_with("[condition.layers]\nhead_motion = { quaternions = \"bad.csv\" }\n", dir / "p.toml");
    DiagnosticList problems;
    const LayerSettings s = parse_layer_settings(p.conditions[1].layers, dir, problems);
    ASSERT_TRUE(problems.empty());
    synth::Trajectory t;
    t.fps = 10.0;
    t.frames.assign(3, synth::Frame{});
    try {
        animate(default_head(), t, nullptr, s);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("bad.csv:3:4: error: y: expected a number, got \"zero\""), std::string::npos)
            << e.what();
    }
}

TEST_F(LayersProtocol, TheBuilderRendersTheStackAndRecordsItInTheManifest) {
    const Protocol p = protocol_with("[condition.layers]\nexpression = \"surprised\"\nhead_motion = \"idle\"\ngaze = true\n",
                                     dir / "p.toml");
    // Small frames for speed.
    std::string text = read_text_file(dir / "p.toml");
    text += "[render]\nfps = 30\nwidth = 96\nheight = 72\n";
    write_text_file(dir / "p.toml", text);
    BuildSettings b;
    b.protocol_path = dir / "p.toml";
    b.out_dir = dir / "out";
    b.jobs = 2;
    const BuildReport r = build_stimuli(b);
    EXPECT_EQ(r.rendered, 4u);  // 2 sentences × 2 conditions
    const auto manifest = nlohmann::json::parse(read_text_file(dir / "out" / "manifest.json"));
    ASSERT_EQ(manifest["stimuli"].size(), 4u);
    for (const auto& e : manifest["stimuli"]) {
        SCOPED_TRACE(e["condition"].get<std::string>());
        if (e["condition"] == "plain") {
            EXPECT_FALSE(e.contains("layers"));
        } else {
            ASSERT_TRUE(e.contains("layers"));
            const auto& l = e["layers"];
            ASSERT_EQ(l.size(), 5u);  // speech, blink, gaze, head motion, expression
            EXPECT_EQ(l[0]["kind"], "speech");
            EXPECT_EQ(l[1]["kind"], "blink");
            EXPECT_EQ(l[2]["kind"], "gaze");
            EXPECT_TRUE(l[2]["seed"].is_number());
            EXPECT_EQ(l[3]["source"], "idle");
            EXPECT_EQ(l[4]["name"], "surprised");
            EXPECT_EQ(l[4]["sha256"], sha256_file(default_expressions_file()));
        }
        // Every model stimulus's articulation holds, layers on.
        EXPECT_EQ(e["articulation"]["bilabials_closed"], e["articulation"]["bilabials"]);
    }
    const VerifyReport v = verify_stimuli(b);
    EXPECT_EQ(v.verified, 4u);
    EXPECT_TRUE(v.problems.empty());
}

}  // namespace
}  // namespace avsi::stimuli
