// Swedish on the face (protocols/languages/sv/): the three-way contrast of
// the close front vowels measured on the head by `avsi measure` — outrounded
// /yː/ (YY) protrudes the lips beyond spread /iː/ (IY), inrounded /ʉː/ (UX)
// is narrower than /iː/ without /yː/'s protrusion — on the built-in head, in
// Swedish running speech through espeak-ng sv, and on the exported glTF/ARKit
// head, whose rounding uses mouthPucker and mouthFunnel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/tts.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/gltf_head.h"
#include "avsi/synth/control_model.h"
#include "support/heads.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi::stimuli {
namespace {

namespace fs = std::filesystem;

const fs::path models_dir = fs::path(AVSI_PROTOCOLS_DIR) / "models";

// The stated margins, stricter than ArticulationLimits' defaults (1 and 3 mm).
constexpr double outrounding_margin_mm = 2.0;  // /yː/ protrusion beyond /iː/ and beyond /ʉː/
constexpr double inrounding_margin_mm = 5.0;   // /ʉː/ narrower than /iː/

// /iː yː ʉː/ in the frames of /t/ and /s/: "ti: ty: tu- si: sy: su-".
PhoneSequence close_front_phones() {
    PhoneSequence phones;
    double t = 0.0;
    auto add = [&](const std::string& symbol, double d, bool stressed = false) {
        phones.push_back({symbol, t, t + d, stressed});
        t += d;
    };
    add("sil", 0.2);
    for (const char* c : {"T", "S"})
        for (const char* v : {"IY", "YY", "UX"}) {
            add(c, 0.08);
            add(v, 0.22, true);
            add("sil", 0.15);
        }
    return phones;
}

void expect_contrast(const ArticulationSummary& s, const std::string& where) {
    SCOPED_TRACE(where);
    ASSERT_TRUE(s.close_front_checked);
    EXPECT_GE(s.outrounded_yy.protrusion_mm - s.spread_iy.protrusion_mm, outrounding_margin_mm);
    EXPECT_LE(s.inrounded_ux.width_mm, s.spread_iy.width_mm - inrounding_margin_mm);
    EXPECT_LE(s.inrounded_ux.protrusion_mm, s.outrounded_yy.protrusion_mm - outrounding_margin_mm);
    EXPECT_TRUE(s.close_front_problems.empty());
    for (const auto& p : s.close_front_problems) ADD_FAILURE() << p;
}

TEST(SwedishLips, MeasureShowsTheThreeWayContrastWithItsNumbers) {
    const fs::path dir = test::temp_dir("swedish_lips_cli");
    write_phones_tsv(dir / "p.tsv", close_front_phones());
    const auto r = test::run_avsi("measure --model " + test::shell_quote((models_dir / "sv" / "rule.json").string()) +
                                  " --phones " + test::shell_quote((dir / "p.tsv").string()) + " --out " +
                                  test::shell_quote((dir / "m.csv").string()) + " --check");
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    // "close front vowels: /iː/ width W mm, protrusion P mm; /yː/ …; /ʉː/ …"
    const std::regex line(R"(close front vowels: /iː/ width ([-0-9.]+) mm, protrusion ([-0-9.]+) mm; /yː/ width )"
                          R"(([-0-9.]+) mm, protrusion ([-0-9.]+) mm; /ʉː/ width ([-0-9.]+) mm, protrusion ([-0-9.]+) mm)");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.out, m, line)) << r.out;
    const double iy_w = std::stod(m[1]), iy_p = std::stod(m[2]), yy_p = std::stod(m[4]);
    const double ux_w = std::stod(m[5]), ux_p = std::stod(m[6]);
    EXPECT_GE(yy_p - iy_p, outrounding_margin_mm) << r.out;
    EXPECT_LE(ux_w, iy_w - inrounding_margin_mm) << r.out;
    EXPECT_LE(ux_p, yy_p - outrounding_margin_mm) << r.out;
    EXPECT_EQ(r.out.find("problem:"), std::string::npos) << r.out;
    fs::remove_all(dir);
}

TEST(SwedishLips, EnglishModelRefusesSwedishPhonesNamingTheLanguage) {
    const fs::path dir = test::temp_dir("swedish_lips_en");
    write_phones_tsv(dir / "p.tsv", close_front_phones());
    const auto r = test::run_avsi("measure --model " + test::shell_quote((models_dir / "rule.json").string()) +
                                  " --phones " + test::shell_quote((dir / "p.tsv").string()) + " --out " +
                                  test::shell_quote((dir / "m.csv").string()));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("phone of the de, sv table"), std::string::npos) << r.err;
    fs::remove_all(dir);
}

TEST(SwedishLips, ContrastHoldsInSwedishRunningSpeech) {
    const ArticulationMeter meter(test::default_head());
    const auto rule = synth::load_model(models_dir / "sv" / "rule.json");
    TtsSettings tts;
    set_tts_voice(tts, "espeak:sv");
    // Sentences written for this test, rich in /iː yː ʉː/.
    const std::vector<std::string> sentences = {
        "Min syster Ylva bor i ett hus vid en lugn sjö nära byn.",
        "Vi såg fyra vita fiskar i det klara vattnet vid muren.",
        "Det blev tyst i huset när hyran skulle betalas i tid."};
    for (const auto& text : sentences) {
        const PhoneSequence phones = synthesize_speech(text, tts).phones;
        const auto s = check_articulation(phones, 30.0, meter.measure(rule->synthesize(phones, 30.0)));
        expect_contrast(s, text);
        EXPECT_EQ(s.bilabials_closed, s.bilabials) << text;
        EXPECT_EQ(s.labiodentals_reached, s.labiodentals) << text;
        EXPECT_EQ(s.interpenetrating_frames, 0u) << text;
    }
}

TEST(SwedishLips, ExportedArkitHeadHasPuckerAndFunnelAndShowsTheContrast) {
    const fs::path dir = test::temp_dir("swedish_lips_gltf");
    export_gltf_head(test::default_head(), dir / "head.glb");
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, (dir / "head.glb").string())) << err;
    std::vector<std::string> names;
    for (const auto& mesh : model.meshes)
        if (mesh.extras.Has("targetNames"))
            for (std::size_t k = 0; k < mesh.extras.Get("targetNames").ArrayLen(); ++k)
                names.push_back(mesh.extras.Get("targetNames").Get(static_cast<int>(k)).Get<std::string>());
    EXPECT_NE(std::find(names.begin(), names.end(), "mouthFunnel"), names.end());
    EXPECT_NE(std::find(names.begin(), names.end(), "mouthPucker"), names.end());

    const Head gltf = load_gltf_head(dir / "head.glb");
    const ArticulationMeter meter(gltf);
    const auto rule = synth::load_model(models_dir / "sv" / "rule.json");
    const PhoneSequence phones = close_front_phones();
    expect_contrast(check_articulation(phones, 30.0, meter.measure(rule->synthesize(phones, 30.0))), "glTF head");
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi::stimuli
