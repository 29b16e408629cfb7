// Level of detail (stimuli/lod.h): the built-in head at three levels —
// triangle counts decreasing, the kept regions untouched, the seams as
// watertight as before, the rig carried over (every vertex of a simplified
// head poses exactly where its original does), the articulation measures
// of a running-speech sentence within 0.2 mm of full detail, and rendered
// frames of that sentence within a stated image difference; triangle
// budgets (and impossible ones), the automatic choice, a lab's OBJ + rig and
// glTF head, the render settings and the builder's manifest.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/gltf_head.h"
#include "avsi/stimuli/lod.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/synth/control_model.h"
#include "support/heads.h"
#include "support/temp_dir.h"

namespace avsi::stimuli {
namespace {

using test::default_head;

// Levels 1-3 of the built-in head, made once.
const LodResult& level(int k) {
    static const std::map<int, LodResult> levels = [] {
        std::map<int, LodResult> out;
        for (int l = 0; l <= 3; ++l) out.emplace(l, head_at_level(default_head(), l));
        return out;
    }();
    return levels.at(k);
}

// A triangle as the sorted original vertex indices of its corners.
using Tri = std::array<std::uint32_t, 3>;
Tri tri(const std::vector<std::uint32_t>& idx, std::size_t t, const std::vector<std::uint32_t>* source) {
    Tri r;
    for (int k = 0; k < 3; ++k) {
        const auto v = idx[3 * t + std::size_t(k)];
        r[std::size_t(k)] = source ? (*source)[v] : v;
    }
    std::sort(r.begin(), r.end());
    return r;
}

// The open edges of a mesh (used by exactly one triangle) with vertices
// welded by position (a texture seam splits vertices but leaves no hole), as
// pairs of the full head's vertex indices: the holes in the surface.
std::set<std::pair<std::uint32_t, std::uint32_t>> open_edges(const HeadMesh& mesh,
                                                             const std::vector<std::uint32_t>* source) {
    const auto& full = default_head().mesh.positions;
    std::map<std::array<float, 3>, std::uint32_t> weld;
    for (std::uint32_t v = 0; v < full.size(); ++v) weld.emplace(std::array<float, 3>{full[v].x, full[v].y, full[v].z}, v);
    auto welded = [&](std::uint32_t v) {
        const auto& p = full[v];
        return weld.at({p.x, p.y, p.z});
    };
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> count;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        Tri c = tri(mesh.indices, t, source);
        for (auto& v : c) v = welded(v);
        std::sort(c.begin(), c.end());
        if (c[0] == c[1] || c[1] == c[2]) continue;
        ++count[{c[0], c[1]}];
        ++count[{c[1], c[2]}];
        ++count[{c[0], c[2]}];
    }
    std::set<std::pair<std::uint32_t, std::uint32_t>> out;
    for (const auto& [e, n] : count)
        if (n == 1) out.insert(e);
    return out;
}

// A random pose over every channel's range.
Pose random_pose(std::mt19937& rng) {
    Pose p;
    for (std::size_t i = 0; i < synth::param_count; ++i) {
        const auto& info = synth::params()[i];
        p.params[i] = std::uniform_real_distribution<double>(info.min, info.max)(rng);
    }
    std::uniform_real_distribution<double> unit(0.0, 1.0), both(-1.0, 1.0);
    p.blink = unit(rng);
    p.tongue_tip = unit(rng);
    p.gaze_left = both(rng);
    p.gaze_up = both(rng);
    return p;
}

// Every vertex of the simplified head poses bit for bit where its original does.
void expect_rig_carried_over(const Head& full, const LodResult& lod, int poses) {
    ASSERT_EQ(lod.source_vertex.size(), lod.head.mesh.positions.size());
    std::mt19937 rng(24);
    std::vector<glm::vec3> a, b;
    std::size_t compared = 0;
    for (int i = 0; i < poses; ++i) {
        const Pose pose = random_pose(rng);
        pose_positions(full, pose, a);
        pose_positions(lod.head, pose, b);
        for (std::size_t v = 0; v < b.size(); ++v) {
            ASSERT_EQ(b[v], a[lod.source_vertex[v]]) << "vertex " << v << " (was " << lod.source_vertex[v] << "), pose " << i;
            ++compared;
        }
    }
    EXPECT_GT(compared, 0u);
}

// The sentence the articulation and image tests speak: the first of the
// running-speech sentences, timed by espeak-ng, through the rule model.
const synth::Trajectory& sentence_trajectory() {
    static const synth::Trajectory t = [] {
        std::ifstream in(std::filesystem::path(AVSI_TEST_DATA_DIR) / "articulation" / "sentences.txt");
        std::string sentence;
        for (std::string line; std::getline(in, line);)
            if (!trim(line).empty() && line[0] != '#') {
                sentence = trim(line);
                break;
            }
        const auto phones = synthesize_speech(sentence).phones;
        const auto model = synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json");
        return model->synthesize(phones, 30.0);
    }();
    return t;
}

TEST(Lod, ThreeLevelsHaveFewerTrianglesEachAndKeepTheMouthAndEyes) {
    const auto keep = lod_kept_triangles(default_head());
    std::set<Tri> kept;
    for (std::size_t t = 0; t < keep.size(); ++t)
        if (keep[t]) kept.insert(tri(default_head().mesh.indices, t, nullptr));
    ASSERT_GT(kept.size(), 1000u);
    // Every triangle of the lips, teeth, tongue, mouth cavity and eyes is kept.
    for (std::size_t t = 0; t < keep.size(); ++t) {
        const auto& g = default_head().mesh.group_names[std::size_t(default_head().mesh.triangle_group[t])];
        if (g == "upper_lip" || g == "lower_lip" || g == "upper_teeth" || g == "lower_teeth" || g == "eyes" ||
            g == "cornea" || g == "tongue") {
            ASSERT_TRUE(keep[t]) << g;
        }
    }
    EXPECT_FALSE(lod_keeps_group("skin"));
    EXPECT_FALSE(lod_keeps_group("hair"));
    EXPECT_TRUE(lod_keeps_group("Upper_Teeth"));

    std::size_t previous = default_head().mesh.triangle_count();
    EXPECT_EQ(level(0).triangles, previous);
    const auto full_border = open_edges(default_head().mesh, nullptr);
    EXPECT_GT(full_border.size(), 100u);
    for (int l = 1; l <= 3; ++l) {
        SCOPED_TRACE(fmt::format("level {}", l));
        const LodResult& r = level(l);
        std::printf("level %d: %zu triangles (%zu kept), %zu vertices, error %.3f mm\n", l, r.triangles,
                    r.kept_triangles, r.head.mesh.positions.size(), r.error_mm);
        EXPECT_EQ(r.triangles, r.head.mesh.triangle_count());
        EXPECT_LT(r.triangles, previous);
        // Each level takes away a fifth or more of what is left to simplify,
        // within its error bound.
        const double rest = double(default_head().mesh.triangle_count() - r.kept_triangles);
        EXPECT_LE(double(r.triangles - r.kept_triangles), rest * std::pow(0.8, l));
        EXPECT_LE(r.error_mm, lod_level_max_error_mm(l) * 1.001);
        previous = r.triangles;
        EXPECT_EQ(r.kept_triangles, kept.size());
        // The kept triangles are all there, unchanged.
        std::set<Tri> present;
        for (std::size_t t = 0; t < r.head.mesh.triangle_count(); ++t) present.insert(tri(r.head.mesh.indices, t, &r.source_vertex));
        for (const auto& k : kept) ASSERT_TRUE(present.count(k));
        // The border locked: the same holes as the full head (the neck, the
        // seams between groups), no new ones.
        const auto lod_border = open_edges(r.head.mesh, &r.source_vertex);
        std::vector<std::pair<std::uint32_t, std::uint32_t>> diff;
        std::set_symmetric_difference(lod_border.begin(), lod_border.end(), full_border.begin(), full_border.end(),
                                      std::back_inserter(diff));
        EXPECT_TRUE(diff.empty()) << diff.size() << " open edges differ, e.g. " << diff[0].first << "-" << diff[0].second;
        // Per-vertex attributes carried over; no unused vertex but the rig's indexed ones.
        ASSERT_EQ(r.head.mesh.uvs.size(), r.head.mesh.positions.size());
        for (std::size_t v = 0; v < r.source_vertex.size(); ++v) {
            ASSERT_EQ(r.head.mesh.positions[v], default_head().mesh.positions[r.source_vertex[v]]);
            ASSERT_EQ(r.head.mesh.colors[v], default_head().mesh.colors[r.source_vertex[v]]);
            ASSERT_EQ(r.head.mesh.uvs[v], default_head().mesh.uvs[r.source_vertex[v]]);
        }
        EXPECT_EQ(r.head.mesh.triangle_group.size(), r.triangles);
        EXPECT_GT(r.error_mm, 0.0);
    }
}

TEST(Lod, RigAndLandmarksCarryOverSoEveryVertexPosesAsInTheFullHead) {
    for (int l = 1; l <= 3; ++l) {
        SCOPED_TRACE(fmt::format("level {}", l));
        const LodResult& r = level(l);
        expect_rig_carried_over(default_head(), r, 12);
        // The landmarks name the same vertices.
        const auto& a = *default_head().articulation;
        const auto& b = *r.head.articulation;
        ASSERT_EQ(a.upper_lip_contour.size(), b.upper_lip_contour.size());
        for (std::size_t i = 0; i < a.upper_lip_contour.size(); ++i) {
            EXPECT_EQ(r.source_vertex[b.upper_lip_contour[i]], a.upper_lip_contour[i]);
            EXPECT_EQ(r.source_vertex[b.lower_lip_contour[i]], a.lower_lip_contour[i]);
        }
        EXPECT_EQ(r.source_vertex[b.mouth_corner_left], a.mouth_corner_left);
        EXPECT_EQ(r.source_vertex[b.upper_lip_point], a.upper_lip_point);
        for (std::size_t i = 0; i < a.upper_incisor_edge.size(); ++i)
            EXPECT_EQ(r.source_vertex[b.upper_incisor_edge[i]], a.upper_incisor_edge[i]);
        // Every transform keeps its entries at the surviving vertices, no others.
        ASSERT_EQ(r.head.transforms.size(), default_head().transforms.size());
        std::size_t entries = 0;
        for (std::size_t t = 0; t < default_head().transforms.size(); ++t) {
            const auto& ft = default_head().transforms[t];
            const auto& lt = r.head.transforms[t];
            ASSERT_EQ(lt.vertices.size(), lt.weights.size());
            if (ft.kind == TransformKind::Blendshape) {
                ASSERT_EQ(lt.offsets.size(), lt.vertices.size());
            }
            entries += lt.vertices.size();
        }
        EXPECT_GT(entries, 0u);
        EXPECT_EQ(r.head.lip_contact->mesh.moved.size(), default_head().lip_contact->mesh.moved.size());
    }
}

TEST(Lod, ArticulationMeasuresOfRunningSpeechWithinAFifthOfAMillimetreAtEveryLevel) {
    const auto& trajectory = sentence_trajectory();
    ASSERT_GT(trajectory.size(), 30u);
    const auto full = ArticulationMeter(default_head()).measure(trajectory);
    for (int l = 1; l <= 3; ++l) {
        const auto lod = ArticulationMeter(level(l).head).measure(trajectory);
        ASSERT_EQ(lod.size(), full.size());
        double worst = 0.0;
        for (std::size_t f = 0; f < full.size(); ++f) {
            const auto& a = full[f];
            const auto& b = lod[f];
            for (const auto d : {a.aperture_mid_mm - b.aperture_mid_mm, a.aperture_min_mm - b.aperture_min_mm,
                                 a.aperture_max_mm - b.aperture_max_mm, a.aperture_all_min_mm - b.aperture_all_min_mm,
                                 a.mouth_width_mm - b.mouth_width_mm, a.upper_protrusion_mm - b.upper_protrusion_mm,
                                 a.lower_protrusion_mm - b.lower_protrusion_mm, a.jaw_opening_mm - b.jaw_opening_mm,
                                 a.lip_to_incisors_mm - b.lip_to_incisors_mm})
                worst = std::max(worst, std::abs(d));
        }
        std::printf("level %d: largest articulation difference over %zu frames: %.4f mm\n", l, full.size(), worst);
        EXPECT_LE(worst, 0.2) << "level " << l;
    }
    // The measures do move over the sentence (the comparison is not of rest poses).
    double lo = 1e9, hi = -1e9;
    for (const auto& m : full) lo = std::min(lo, m.aperture_mid_mm), hi = std::max(hi, m.aperture_mid_mm);
    EXPECT_GT(hi - lo, 5.0);
}

// Mean absolute RGB difference (0-255) and PSNR (dB) between two images.
std::pair<double, double> image_difference(const Image& a, const Image& b) {
    EXPECT_EQ(a.rgb.size(), b.rgb.size());
    double abs_sum = 0.0, sq_sum = 0.0;
    for (std::size_t i = 0; i < a.rgb.size(); ++i) {
        const double d = double(a.rgb[i]) - double(b.rgb[i]);
        abs_sum += std::abs(d);
        sq_sum += d * d;
    }
    const double n = double(a.rgb.size());
    const double mse = sq_sum / n;
    return {abs_sum / n, mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0};
}

// The stated bound: over a sentence's frames at the stimulus resolution,
// every level's mean absolute RGB difference from full detail is under 1.0
// (of 255) and its PSNR over 30 dB; coarser levels differ more.
TEST(Lod, RenderedSentenceFramesStayWithinTheStatedImageDifference) {
    const auto& trajectory = sentence_trajectory();
    RenderSettings rs;  // 640 x 480, the stimulus resolution
    OffscreenRenderer full(default_head(), rs);
    EXPECT_EQ(full.lod(), nullptr);
    std::vector<Pose> poses;
    for (std::size_t f = 0; f < trajectory.size(); f += 8) {
        Pose p;
        p.params = trajectory.frames[f];
        poses.push_back(p);
    }
    std::vector<Image> reference;
    for (const auto& p : poses) reference.push_back(full.render(p));
    double previous = 0.0;
    for (int l = 1; l <= 3; ++l) {
        RenderSettings lrs = rs;
        lrs.lod.level = l;
        OffscreenRenderer renderer(default_head(), lrs);
        ASSERT_NE(renderer.lod(), nullptr);
        EXPECT_EQ(renderer.head().mesh.triangle_count(), level(l).triangles);
        double mad = 0.0, worst_psnr = 99.0;
        for (std::size_t i = 0; i < poses.size(); ++i) {
            const auto [m, psnr] = image_difference(reference[i], renderer.render(poses[i]));
            mad += m / double(poses.size());
            worst_psnr = std::min(worst_psnr, psnr);
        }
        std::printf("level %d: mean |RGB difference| %.3f, lowest PSNR %.1f dB over %zu frames\n", l, mad, worst_psnr,
                    poses.size());
        EXPECT_GT(mad, 0.0) << "level " << l << " draws the full head";
        EXPECT_LT(mad, 1.0) << "level " << l;
        EXPECT_GT(worst_psnr, 30.0) << "level " << l;
        EXPECT_GE(mad, previous * 0.9) << "level " << l;
        previous = mad;
    }
}

TEST(Lod, TriangleBudgetIsMetOrRefusedWithTheSmallestThatWorks) {
    const std::size_t full = default_head().mesh.triangle_count();
    const LodResult& l1 = level(1);
    const std::size_t budget = (l1.triangles + level(2).triangles) / 2;
    // The finest level within the budget.
    const LodResult r = head_within_budget(default_head(), budget);
    EXPECT_LE(r.triangles, budget);
    EXPECT_EQ(r.level, 2);
    EXPECT_EQ(r.triangles, level(2).triangles);
    EXPECT_EQ(head_within_budget(default_head(), l1.triangles).level, 1);
    EXPECT_EQ(head_within_budget(default_head(), level(3).triangles).level, 3);
    EXPECT_EQ(r.chosen_by, "max_triangles");
    expect_rig_carried_over(default_head(), r, 2);
    EXPECT_EQ(head_within_budget(default_head(), full).triangles, full);
    EXPECT_EQ(head_within_budget(default_head(), full * 2).triangles, full);
    // Below what the kept regions alone need: refused, naming the head's file and the smallest budget.
    try {
        head_within_budget(default_head(), level(3).triangles - 1);
        FAIL() << "an impossible budget was accepted";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(default_head_rig().string()), std::string::npos) << what;
        EXPECT_NE(what.find("max_triangles"), std::string::npos) << what;
        EXPECT_NE(what.find("at least"), std::string::npos) << what;
        EXPECT_NE(what.find("at least " + std::to_string(level(3).triangles) + " triangles"), std::string::npos) << what;
        EXPECT_NE(what.find(std::to_string(l1.kept_triangles) + " triangles"), std::string::npos) << what;
    }
    EXPECT_THROW(head_at_level(default_head(), max_lod_level + 1), UsageError);
    EXPECT_THROW(head_at_level(default_head(), -1), UsageError);
    LodSettings both;
    both.level = 2;
    both.max_triangles = 20000;
    EXPECT_THROW(level_of_detail(default_head(), both, 480, 340.0), UsageError);
    LodSettings parsed;
    parse_lod_level("3", "--lod", parsed);
    EXPECT_EQ(parsed.level, 3);
    parse_lod_level("auto", "--lod", parsed);
    EXPECT_TRUE(parsed.automatic);
    EXPECT_THROW(parse_lod_level("4", "--lod", parsed), UsageError);
    EXPECT_THROW(parse_lod_level("high", "--lod", parsed), UsageError);
}

TEST(Lod, AutomaticLevelFollowsTheHeadsSizeOnScreen) {
    LodSettings lod;
    lod.automatic = true;
    // A large frame shows the head at full detail; smaller ones coarser, never finer.
    int previous = -1;
    for (const int height : {4320, 480, 120, 48}) {
        const LodResult r = level_of_detail(default_head(), lod, height, 340.0);
        const double px_per_mm = double(height) / 340.0;
        std::printf("frame height %d: head %.0f px high, level %d, error %.3f mm = %.2f px\n", height,
                    r.head_height_px, r.level, r.error_mm, r.error_mm * px_per_mm);
        EXPECT_EQ(r.chosen_by, "auto");
        EXPECT_NEAR(r.head_height_px, default_head().landmarks.head_height * px_per_mm, 1e-3);
        EXPECT_LE(r.error_mm * px_per_mm, lod.max_error_px + 1e-9);
        EXPECT_GE(r.level, previous);
        previous = r.level;
    }
    EXPECT_EQ(level_of_detail(default_head(), lod, 4320, 340.0).level, 0);
    EXPECT_EQ(previous, max_lod_level);
}

// A lab's heads: an OBJ + rig of its own and a glTF head (the built-in one
// exported) simplify with their rigs carried over.
TEST(Lod, WorksOnALabsObjAndGltfHeads) {
    const auto dir = test::temp_dir("lod_lab");
    const auto head_dir = default_head_obj().parent_path();
    const Head dark = load_head(head_dir / "head-dark.obj", head_dir / "head-dark.rig.json");
    export_gltf_head(default_head(), dir / "head.glb");
    const Head gltf = load_gltf_head(dir / "head.glb", default_blendshape_mapping());
    for (const Head* h : {&dark, &gltf}) {
        SCOPED_TRACE(h->obj_path.string());
        const LodResult r = head_at_level(*h, 3);
        EXPECT_LT(double(r.triangles), 0.85 * double(h->mesh.triangle_count()));
        expect_rig_carried_over(*h, r, 3);
        const auto trajectory = sentence_trajectory();
        const auto a = ArticulationMeter(*h).measure(trajectory);
        const auto b = ArticulationMeter(r.head).measure(trajectory);
        for (std::size_t f = 0; f < a.size(); ++f) ASSERT_NEAR(a[f].aperture_min_mm, b[f].aperture_min_mm, 0.2);
    }
    std::filesystem::remove_all(dir);
}

// The builder draws the simplified head and records the level in the
// manifest's render settings; a default build records none.
TEST(Lod, BuilderRecordsTheLevelInTheManifest) {
    const auto dir = test::temp_dir("lod_build");
    BuildSettings s;
    s.protocol_path = std::string(AVSI_TEST_DATA_DIR) + "/stimuli/build/protocol.toml";
    s.out_dir = dir / "full";
    s.jobs = 2;
    s.max_sentences = 1;
    build_stimuli(s);
    const auto full = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    EXPECT_FALSE(full["settings"]["render"].contains("lod"));
    s.out_dir = dir / "lod";
    s.lod.level = 3;
    build_stimuli(s);
    const auto lod = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    const auto& j = lod["settings"]["render"]["lod"];
    EXPECT_EQ(j["level"], 3);
    EXPECT_EQ(j["chosen_by"], "level");
    EXPECT_EQ(j["triangles"], level(3).triangles);
    EXPECT_EQ(j["full_triangles"], default_head().mesh.triangle_count());
    EXPECT_NE(j["simplifier"].get<std::string>().find("meshoptimizer"), std::string::npos);
    // Every input hash covers the setting (the stimuli are rebuilt when it changes).
    std::map<std::string, nlohmann::json> a, b;
    for (const auto& e : full["stimuli"]) a[e["path"].get<std::string>()] = e;
    for (const auto& e : lod["stimuli"]) b[e["path"].get<std::string>()] = e;
    ASSERT_EQ(a.size(), b.size());
    for (const auto& [path, e] : a) {
        EXPECT_NE(e["input_sha256"], b[path]["input_sha256"]) << path;
        if (e.contains("articulation")) {
            EXPECT_EQ(e["articulation"], b[path]["articulation"]) << path;
        }
    }
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace avsi::stimuli
