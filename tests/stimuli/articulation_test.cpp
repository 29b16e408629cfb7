// The face shows what the phones say: the articulation measures against
// hand-computed geometry, the lip contact of the rig, and the phonetic
// constraints on running speech for every default model at 25, 30 and 60 fps
// (tests/data/articulation/sentences.txt), checked on geometry and on
// rendered frames.
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/synth/control_model.h"
#include "avsi/synth/closure_constraint.h"
#include "avsi/synth/target_hold.h"
#include "support/heads.h"
#include "support/run_avsi.h"
#include "support/sentences.h"
#include "support/temp_dir.h"

namespace avsi::stimuli {
namespace {

using synth::index;
using synth::Param;

using test::default_head;

using test::temp_dir;

// A small head made by the test: a flat 40 mm-wide mouth of 5 contour pairs
// (upper at y = 0, lower at y = 0), corners at x = ±20, a lip point each,
// an upper incisal edge 3 mm behind and 1 mm below the lips, a lower one,
// and one lower-lip surface point; its rig moves the lower lip down by
// 4 mm per unit of lower_lip_depression and the upper incisors nowhere.
void write_small_head(const std::filesystem::path& dir, bool with_landmarks) {
    std::string obj = "# test head\n";
    // 0-4 upper contour, 5-9 lower contour, 10 left corner, 11 right corner,
    // 12 upper lip point, 13 lower lip point, 14-15 upper incisal edge,
    // 16-17 lower incisal edge, 18 lower lip surface point.
    for (int i = 0; i < 5; ++i) obj += fmt::format("v {} 0 5\n", -16 + 8 * i);
    for (int i = 0; i < 5; ++i) obj += fmt::format("v {} 0 5\n", -16 + 8 * i);
    obj += "v 20 0 4\nv -20 0 4\nv 0 3 6\nv 0 -3 6\n";
    obj += "v -8 -1 2\nv 8 -1 2\nv -8 -1.5 1\nv 8 -1.5 1\nv 0 -2 4\n";
    obj += "g upper\nf 1 2 13\nf 2 3 13\nf 3 4 13\nf 4 5 13\nf 15 16 1\n";
    obj += "g lower\nf 7 6 14\nf 8 7 14\nf 9 8 14\nf 10 9 14\nf 17 18 19\nf 11 12 19\n";
    write_text_file(dir / "head.obj", obj);
    std::string rig = R"({"format": "avsi-rig", "landmarks": {"head_center": [0,0,0], "head_height": 100,
        "iris_diameter": 10, "left_eye": [30,40,0], "right_eye": [-30,40,0], "mouth_left": [20,0,4],
        "mouth_middle": [0,0,5], "mouth_right": [-20,0,4], "nose_bottom": [0,20,8]},
        "transforms": [{"channel": "lower_lip_depression", "translate": [0, -4, 0], "region": {"groups": ["lower"]}}])";
    if (with_landmarks)
        rig += R"(, "articulation": {"upper_lip_contour": [0,1,2,3,4], "lower_lip_contour": [5,6,7,8,9],
            "mouth_corners": [10, 11], "upper_lip_point": 12, "lower_lip_point": 13,
            "upper_incisor_edge": [14, 15], "lower_incisor_edge": [16, 17], "lower_lip_surface": [18],
            "up": [0,1,0], "forward": [0,0,1]})";
    rig += "}\n";
    write_text_file(dir / "head.rig.json", rig);
}

TEST(Articulation, MeasuresOfASmallHeadMatchItsGeometry) {
    const auto dir = temp_dir("articulation_small_head");
    write_small_head(dir, true);
    const Head h = load_head(dir / "head.obj", dir / "head.rig.json");
    const ArticulationMeter meter(h);
    Pose pose;
    auto m = meter.measure(pose);
    EXPECT_NEAR(m.aperture_mid_mm, 0.0, 1e-6);
    EXPECT_NEAR(m.mouth_width_mm, 40.0, 1e-5);
    EXPECT_NEAR(m.lip_to_incisors_mm, std::sqrt(1.0 + 4.0), 1e-5);  // (0,-2,4) to the edge y = -1, z = 2
    // The lower lip comes down 4 mm per unit; every vertex in group "lower"
    // belongs wholly to it (vertex 13, the lower lip point, moves too).
    pose.params[index(Param::LowerLipDepression)] = 0.5;
    m = meter.measure(pose);
    EXPECT_NEAR(m.aperture_mid_mm, 2.0, 1e-5);
    EXPECT_NEAR(m.aperture_min_mm, 2.0, 1e-5);
    EXPECT_NEAR(m.aperture_max_mm, 2.0, 1e-5);
    EXPECT_NEAR(m.lower_protrusion_mm, 0.0, 1e-6);
    EXPECT_NEAR(m.jaw_opening_mm, 2.0, 1e-5);  // the lower incisors are in group "lower" too
    // Raised, the lower lip passes through the upper (no lip_contact section).
    pose.params[index(Param::LowerLipDepression)] = -0.25;
    m = meter.measure(pose);
    EXPECT_NEAR(m.aperture_all_min_mm, -1.0, 1e-5);
    std::filesystem::remove_all(dir);
}

TEST(Articulation, HeadWithoutLandmarksIsRefusedNamingWhatIsMissing) {
    const auto dir = temp_dir("articulation_no_landmarks");
    write_small_head(dir, false);
    const Head h = load_head(dir / "head.obj", dir / "head.rig.json");
    try {
        ArticulationMeter meter(h);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        const std::string text = e.what();
        EXPECT_NE(text.find("head.rig.json"), std::string::npos) << text;
        for (const auto& name : articulation_landmark_names()) EXPECT_NE(text.find(name), std::string::npos) << name;
    }
    std::filesystem::remove_all(dir);
}

TEST(Articulation, IncompleteLandmarkSectionNamesTheMissingFields) {
    const auto dir = temp_dir("articulation_incomplete");
    write_small_head(dir, true);
    std::string rig = read_text_file(dir / "head.rig.json");
    const auto at = rig.find("\"upper_incisor_edge\": [14, 15], ");
    ASSERT_NE(at, std::string::npos);
    rig.erase(at, std::string("\"upper_incisor_edge\": [14, 15], ").size());
    write_text_file(dir / "head.rig.json", rig);
    try {
        load_head(dir / "head.obj", dir / "head.rig.json");
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("missing landmark(s): upper_incisor_edge"), std::string::npos) << e.what();
    }
    std::filesystem::remove_all(dir);
}

TEST(Articulation, MeasureCommandRefusesAHeadWithoutLandmarksAndMeasuresOneWith) {
    const auto dir = temp_dir("articulation_cli");
    write_small_head(dir, false);
    const std::string traj = (dir / "t.csv").string();
    write_text_file(traj,
                    "time_s,jaw_rotation,lip_rounding,upper_lip_retraction,upper_lip_raise,lower_lip_retraction,"
                    "lower_lip_depression,mouth_corner_stretch_left,mouth_corner_stretch_right,jaw_thrust,jaw_shift\n"
                    "0,0,0,0,0,0,0,0,0,0,0\n0.04,0,0,0,0,0,0.25,0,0,0,0\n");
    const std::string args = "measure --traj " + test::shell_quote(traj) + " --mesh " +
                             test::shell_quote((dir / "head.obj").string()) + " --rig " +
                             test::shell_quote((dir / "head.rig.json").string()) + " --out " +
                             test::shell_quote((dir / "m.csv").string());
    auto r = test::run_avsi(args);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find("head.rig.json"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("articulation"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("upper_lip_contour"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "m.csv"));

    write_small_head(dir, true);
    r = test::run_avsi(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string csv = read_text_file(dir / "m.csv");
    EXPECT_EQ(csv.substr(0, csv.find('\n')), "time_s,aperture_mid_mm,aperture_min_mm,aperture_max_mm,aperture_all_min_mm,"
                                             "mouth_width_mm,upper_protrusion_mm,lower_protrusion_mm,jaw_opening_mm,"
                                             "lip_to_incisors_mm");
    EXPECT_NE(csv.find("\n0.0400,1.0000,1.0000,1.0000,"), std::string::npos) << csv;
    std::filesystem::remove_all(dir);
}

TEST(Articulation, BuiltInHeadMeasuresMatchItsPosedMesh) {
    // The meter poses only the landmarks; pose_head poses every vertex. Both
    // must agree, lip contact included.
    const ArticulationMeter meter(default_head());
    const auto& L = *default_head().articulation;
    Rng rng(17);
    for (int trial = 0; trial < 40; ++trial) {
        SCOPED_TRACE("seed 17, trial " + std::to_string(trial));
        Pose pose;
        for (const auto& info : synth::params())
            pose.params[index(info.param)] = info.min + rng.uniform() * info.range();
        PosedMesh posed;
        pose_head(default_head(), pose, posed);
        const auto m = meter.measure(pose);
        const std::size_t mid = L.upper_lip_contour.size() / 2;
        EXPECT_NEAR(m.aperture_mid_mm, posed.positions[L.upper_lip_contour[mid]].y - posed.positions[L.lower_lip_contour[mid]].y,
                    1e-4);
        EXPECT_NEAR(m.mouth_width_mm,
                    glm::length(posed.positions[L.mouth_corner_left] - posed.positions[L.mouth_corner_right]), 1e-4);
    }
}

TEST(Articulation, LipsNeverPassThroughEachOtherOnTheBuiltInHead) {
    // Any pose within the parameter ranges: the lip contact keeps every pair
    // of the inner-lip contours from crossing.
    const ArticulationMeter meter(default_head());
    Rng rng(2004);
    double lowest = 1e9;
    for (int trial = 0; trial < 2000; ++trial) {
        Pose pose;
        for (const auto& info : synth::params())
            pose.params[index(info.param)] = info.min + rng.uniform() * info.range();
        lowest = std::min(lowest, meter.measure(pose).aperture_all_min_mm);
    }
    EXPECT_GE(lowest, -1e-3) << "seed 2004";
}

TEST(Articulation, BilabialTargetsCloseTheLipsFromAnyLipContext) {
    // The rule table's /p b m/ targets (protocols/rule_targets.tsv) with the
    // unspecified parameters anywhere in their range but for the jaw, which
    // the targets fix: the lips meet (the rig's job: rounding, retraction
    // and corner gestures must not open a closure).
    const auto table = synth::read_rule_targets_tsv(synth::default_hold_targets_path());
    const ArticulationMeter meter(default_head());
    Rng rng(5);
    for (const char* phone : {"P", "B", "M"}) {
        const auto& target = table.at(phone);
        double worst = -1e9;
        for (int trial = 0; trial < 500; ++trial) {
            Pose pose;
            for (const auto& info : synth::params()) {
                const auto& v = target[index(info.param)];
                // Unspecified: anywhere a speech context puts it (the rule
                // table's vowels and consonants span [-0.8, 1] for the lips).
                pose.params[index(info.param)] = v ? *v : std::max(info.min, -0.8) + rng.uniform() * (std::min(info.max, 1.0) - std::max(info.min, -0.8));
            }
            worst = std::max(worst, meter.measure(pose).aperture_max_mm);
        }
        EXPECT_LE(worst, 0.5) << phone << ", seed 5";
    }
}

// ---- Running speech -------------------------------------------------------

using test::test_sentences;
using test::Utterance;
using test::utterances;

// The sentences timed by espeak-ng (en-us, test::utterances), and by the
// default protocol's voice (Festival's HTS voice): two synthesisers' durations.
const std::vector<Utterance>& protocol_voice_utterances() {
    static const std::vector<Utterance> u = [] {
        const Protocol protocol = load_protocol(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "beskow2004-en.toml");
        TtsSettings tts;
        tts.engine = protocol.corpus.tts_engine;
        tts.voice = protocol.corpus.tts_voice;
        std::vector<Utterance> out;
        for (const auto& s : test_sentences()) out.push_back({s, synthesize_speech(s, tts).phones});
        return out;
    }();
    return u;
}

struct ConditionModel {
    std::string name;
    std::shared_ptr<const synth::ControlModel> model;
};

// Every default model file as trained or hand-set: the default protocol's
// model conditions (which post-process none of them) and the MPEG-4
// Cohen-Massaro model, which the protocol does not use.
const std::vector<ConditionModel>& default_models() {
    static const std::vector<ConditionModel> models = [] {
        std::vector<ConditionModel> out;
        const Protocol protocol = load_protocol(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "beskow2004-en.toml");
        std::set<std::filesystem::path> used;
        for (const auto& c : protocol.conditions) {
            if (c.face != FaceMode::Model) continue;
            EXPECT_FALSE(c.closure_hold) << c.name << ": the default protocol shows every model as trained";
            out.push_back({c.name, synth::load_model(c.model)});
            used.insert(std::filesystem::weakly_canonical(c.model));
        }
        for (const char* name : {"rule", "cohen-massaro", "mpeg4-cohen-massaro", "ohman", "ann1", "ann2"}) {
            const auto path = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / (std::string(name) + ".json");
            if (used.count(std::filesystem::weakly_canonical(path))) continue;
            out.push_back({name, synth::load_model(path)});
        }
        return out;
    }();
    return models;
}

// The lip tasks of a frame on the built-in head, as the stimulus builder measures them.
synth::LipTaskFunction lip_tasks(const ArticulationMeter& meter) {
    return [&meter](const synth::Frame& frame) {
        Pose pose;
        pose.params = frame;
        const auto m = meter.measure(pose);
        return synth::LipTaskMeasures{m.aperture_max_mm, m.lip_to_incisors_mm};
    };
}

// Every default model on the sentences as timed by `speech`, at 25, 30 and
// 60 fps: prints each model's closure and contact counts (results of the
// models, not constraints) and returns every failure (lips passing through
// each other).
std::vector<std::string> running_speech_failures(const std::vector<Utterance>& speech) {
    const ArticulationMeter meter(default_head());
    std::vector<std::string> failures;
    for (const auto& cm : default_models()) {
        for (double fps : {25.0, 30.0, 60.0}) {
            std::size_t bilabials = 0, closed = 0, labiodentals = 0, reached = 0;
            for (const auto& u : speech) {
                const auto trajectory = cm.model->synthesize(u.phones, fps);
                const auto summary = check_articulation(u.phones, fps, meter.measure(trajectory));
                bilabials += summary.bilabials;
                closed += summary.bilabials_closed;
                labiodentals += summary.labiodentals;
                reached += summary.labiodentals_reached;
                for (const auto& p : summary.failures(false))
                    failures.push_back(fmt::format("{} at {} fps, \"{}\": {}", cm.name, fps, u.text, p));
            }
            std::printf("%-22s %2.0f fps: bilabials closed %zu/%zu, labiodentals %zu/%zu\n", cm.name.c_str(), fps,
                        closed, bilabials, reached, labiodentals);
            EXPECT_GT(bilabials, 80u);
            EXPECT_GT(labiodentals, 30u);
        }
    }
    return failures;
}

std::string joined(const std::vector<std::string>& lines) {
    std::string all;
    for (const auto& l : lines) all += l + "\n";
    return all;
}

TEST(ArticulationRunningSpeech, NoDefaultModelPassesTheLipsThroughEachOtherAt25_30And60Fps) {
    ASSERT_GE(utterances().size(), 20u);
    ASSERT_EQ(default_models().size(), 6u);  // rule, CM, MPEG-4 CM, Öhman, ANN 1, ANN 2
    const auto failures = running_speech_failures(utterances());
    EXPECT_TRUE(failures.empty()) << failures.size() << " failures:\n" << joined(failures);
}

TEST(ArticulationRunningSpeech, NoDefaultModelPassesTheLipsThroughEachOtherWithTheProtocolsVoice) {
    ASSERT_GE(protocol_voice_utterances().size(), 20u);
    const auto failures = running_speech_failures(protocol_voice_utterances());
    EXPECT_TRUE(failures.empty()) << failures.size() << " failures:\n" << joined(failures);
}

// The rule model (the study's most intelligible condition) articulates every
// segment clearly on the built-in head: every bilabial closes, every
// labiodental reaches the upper teeth, no frame interpenetrates, rounding
// holds, at every frame rate. (Its own targets hold the lips through /p b m
// f v/: that is the rule model as hand-set, not a policy applied to it.)
TEST(ArticulationRunningSpeech, RuleModelMeetsEveryConstraintOnTheBuiltInHead) {
    const ArticulationMeter meter(default_head());
    const std::shared_ptr<const synth::ControlModel> rule =
        synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json");
    for (double fps : {25.0, 30.0, 60.0}) {
        std::size_t bilabials = 0, labiodentals = 0;
        for (const auto& u : utterances()) {
            const auto trajectory = rule->synthesize(u.phones, fps);
            const auto summary = check_articulation(u.phones, fps, meter.measure(trajectory));
            bilabials += summary.bilabials;
            labiodentals += summary.labiodentals;
            EXPECT_EQ(summary.bilabials_closed, summary.bilabials) << fps << " fps, \"" << u.text << "\"";
            EXPECT_EQ(summary.labiodentals_reached, summary.labiodentals) << fps << " fps, \"" << u.text << "\"";
            for (const auto& p : summary.problems()) ADD_FAILURE() << fps << " fps, \"" << u.text << "\": " << p;
        }
        EXPECT_GT(bilabials, 80u);
        EXPECT_GT(labiodentals, 30u);
    }
}

// The closure constraint (closure = "hold") on every default model in
// running speech at 25, 30 and 60 fps: every parameter it does not move is
// the model's output bit for bit in every frame; the ones it moves change
// only in the /p b m f v/ segments' frames and within the fall-off (4σ) of
// them; and every segment gets closure or contact, measured on the head.
TEST(ArticulationRunningSpeech, ClosureConstraintChangesOnlyTheLipsAndOnlyAroundTheSegments) {
    const ArticulationMeter meter(default_head());
    const synth::ClosureSettings settings;
    std::set<std::size_t> moved;
    for (const auto& list : {synth::bilabial_task_params(), synth::labiodental_task_params()})
        for (Param p : list) moved.insert(index(p));
    for (const auto& cm : default_models()) {
        const synth::ClosureConstrainedModel held(cm.model, lip_tasks(meter), settings);
        std::size_t changed_frames = 0;
        for (double fps : {25.0, 30.0, 60.0})
            for (const auto& u : utterances()) {
                const auto raw = cm.model->synthesize(u.phones, fps);
                const auto out = held.synthesize(u.phones, fps);
                ASSERT_EQ(raw.size(), out.size());
                // The frames a segment constrains, and how far each frame is from them.
                std::vector<double> distance(raw.size(), 1e9);
                for (const auto& ph : u.phones) {
                    if (ph.symbol != "P" && ph.symbol != "B" && ph.symbol != "M" && ph.symbol != "F" && ph.symbol != "V")
                        continue;
                    std::vector<std::size_t> inside;
                    for (std::size_t k = 0; k < raw.size(); ++k)
                        if (raw.time_s(k) >= ph.start_s && raw.time_s(k) < ph.end_s) inside.push_back(k);
                    if (inside.empty()) {
                        std::size_t nearest = 0;
                        for (std::size_t k = 1; k < raw.size(); ++k)
                            if (std::fabs(raw.time_s(k) - ph.centre_s()) < std::fabs(raw.time_s(nearest) - ph.centre_s()))
                                nearest = k;
                        inside.push_back(nearest);
                    }
                    for (std::size_t k = 0; k < raw.size(); ++k) {
                        const double d = raw.time_s(k) < raw.time_s(inside.front()) ? raw.time_s(inside.front()) - raw.time_s(k)
                                         : raw.time_s(k) > raw.time_s(inside.back()) ? raw.time_s(k) - raw.time_s(inside.back())
                                                                                       : 0.0;
                        distance[k] = std::min(distance[k], d);
                    }
                }
                for (std::size_t k = 0; k < raw.size(); ++k) {
                    bool changed = false;
                    for (std::size_t p = 0; p < synth::param_count; ++p) {
                        if (!moved.count(p)) {
                            // Bit for bit, not merely equal.
                            EXPECT_EQ(std::memcmp(&raw.frames[k][p], &out.frames[k][p], sizeof(double)), 0)
                                << cm.name << ", " << synth::params()[p].name << " changed at frame " << k;
                            continue;
                        }
                        if (raw.frames[k][p] == out.frames[k][p]) continue;
                        changed = true;
                        EXPECT_LE(distance[k], 4.0 * settings.transition_s + 1e-9)
                            << cm.name << " at " << fps << " fps, \"" << u.text << "\": " << synth::params()[p].name
                            << " changed at " << raw.time_s(k) << " s, " << distance[k] << " s from any segment";
                    }
                    changed_frames += changed ? 1 : 0;
                }
                const auto summary = check_articulation(u.phones, fps, meter.measure(out));
                for (const auto& p : summary.failures(true))
                    ADD_FAILURE() << cm.name << "+hold at " << fps << " fps, \"" << u.text << "\": " << p;
            }
        std::printf("%-22s frames changed by the closure constraint: %zu\n", cm.name.c_str(), changed_frames);
    }
}

// Pixels of the oral cavity, teeth and tongue in a region render.
std::size_t interior_pixels(const Image& regions, const Head& h) {
    std::vector<bool> interior(h.mesh.group_names.size() + 1, false);
    for (const char* g : {"upper_cavity", "lower_cavity", "upper_teeth", "lower_teeth", "tongue"}) {
        const int gi = h.mesh.group_index(g);
        if (gi >= 0) interior[static_cast<std::size_t>(gi) + 1] = true;
    }
    std::size_t n = 0;
    for (std::size_t i = 0; i < regions.rgb.size(); i += 3)
        if (regions.rgb[i] < interior.size() && interior[regions.rgb[i]]) ++n;
    return n;
}

TEST(ArticulationRunningSpeech, TheMeasuredClosureIsWhatTheRenderedFrameShows) {
    // Rendered, not only measured: at the frame each /p b m/ segment of two
    // sentences is judged by, the region render at the stimuli's 640 × 480
    // shows no pixel of the oral cavity, teeth or tongue when the measures
    // say the lips are closed, and shows some when they say the lips stay
    // more than 2 mm apart; a frame of an open vowel in the same utterance
    // shows them (so the test can see them).
    RenderSettings rs;
    OffscreenRenderer renderer(default_head(), rs);
    const ArticulationMeter meter(default_head());
    std::size_t closed_seen = 0, open_seen = 0;
    for (const auto& cm : default_models()) {
        for (std::size_t u = 0; u < 2; ++u) {
            const auto& utt = utterances()[u];
            const auto trajectory = cm.model->synthesize(utt.phones, 30.0);
            const auto summary = check_articulation(utt.phones, 30.0, meter.measure(trajectory));
            Pose pose;
            for (const auto& s : summary.segments) {
                if (s.kind != SegmentClass::Bilabial) continue;
                pose.params = trajectory.frames[s.best_frame];
                const std::size_t interior = interior_pixels(renderer.render(pose, RenderMode::Regions), default_head());
                if (s.ok) {
                    ++closed_seen;
                    EXPECT_EQ(interior, 0u) << cm.name << ", \"" << utt.text << "\", " << s.phone << " at " << s.start_s
                                            << " s, frame " << s.best_frame << " measured closed";
                } else if (s.best_mm > 2.0) {
                    ++open_seen;
                    EXPECT_GT(interior, 0u) << cm.name << ", \"" << utt.text << "\", " << s.phone << " at " << s.start_s
                                            << " s measured " << s.best_mm << " mm open";
                }
            }
            std::size_t widest = 0;
            for (std::size_t k = 1; k < trajectory.size(); ++k)
                if (trajectory.value(k, Param::JawRotation) > trajectory.value(widest, Param::JawRotation)) widest = k;
            pose.params = trajectory.frames[widest];
            EXPECT_GT(interior_pixels(renderer.render(pose, RenderMode::Regions), default_head()), 50u) << cm.name;
        }
    }
    EXPECT_GT(closed_seen, 10u);
    std::printf("bilabial frames rendered: %zu measured closed, %zu measured open by > 2 mm\n", closed_seen, open_seen);
}

}  // namespace
}  // namespace avsi::stimuli
