// The stimulus-set builder on a minimal protocol: every stimulus decodes to
// its manifest frame count, a rebuild renders nothing and gives the same
// manifest hashes, and a fresh build elsewhere gives identical hashes.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "avsi/core/audio.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/gltf_head.h"
#include "avsi/stimuli/head.h"
#include "avsi/stimuli/video.h"
#include "avsi/vocoder/masking.h"
#include "support/heads.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi::stimuli {
namespace {

struct BuilderFixture : ::testing::Test {
    std::filesystem::path dir = test::temp_dir("builder_test");
    void TearDown() override { std::filesystem::remove_all(dir); }
    BuildSettings settings(const std::string& name) {
        BuildSettings s;
        s.protocol_path = std::string(AVSI_TEST_DATA_DIR) + "/stimuli/build/protocol.toml";
        s.out_dir = dir / name;
        s.jobs = 2;
        return s;
    }
    static std::vector<std::string> hashes(const std::filesystem::path& manifest) {
        std::vector<std::string> out;
        const auto json = nlohmann::json::parse(read_text_file(manifest));  // outlives the loop
        for (const auto& e : json["stimuli"])
            out.push_back(e["path"].get<std::string>() + " " + e["sha256"].get<std::string>());
        return out;
    }
};

TEST_F(BuilderFixture, BuildsEveryStimulusThenSkipsThemAndIsDeterministic) {
    const BuildReport first = build_stimuli(settings("a"));
    EXPECT_EQ(first.total, 6u);
    EXPECT_EQ(first.rendered, 6u);
    const auto manifest = dir / "a" / "manifest.json";
    const auto json = nlohmann::json::parse(read_text_file(manifest));
    ASSERT_EQ(json["stimuli"].size(), 6u);
    for (const auto& e : json["stimuli"]) {
        SCOPED_TRACE(e["path"].get<std::string>());
        const DecodedVideo v = decode_video(dir / "a" / e["path"].get<std::string>());
        EXPECT_EQ(v.frame_count, e["frames"].get<std::size_t>());
        EXPECT_DOUBLE_EQ(v.fps, 30.0);
        EXPECT_NEAR(v.audio.duration_s(), v.video_duration_s, 1.0 / 30.0);
        EXPECT_EQ(sha256_file(dir / "a" / e["path"].get<std::string>()), e["sha256"].get<std::string>());
    }

    const auto first_hashes = hashes(manifest);
    const BuildReport second = build_stimuli(settings("a"));
    EXPECT_EQ(second.rendered, 0u);
    EXPECT_EQ(second.skipped, 6u);
    EXPECT_EQ(hashes(manifest), first_hashes);

    // Two fresh builds by the command, each in its own process, and one more
    // in this process (after other speech) give identical files.
    for (const char* name : {"b", "c"}) {
        const test::CliResult r =
            test::run_avsi({"build-stimuli", settings(name).protocol_path.string(), "--out", (dir / name).string(), "--jobs", "2"});
        ASSERT_EQ(r.exit_code, 0) << r.output();
    }
    EXPECT_EQ(hashes(dir / "b" / "manifest.json"), hashes(dir / "c" / "manifest.json"));
    build_stimuli(settings("d"));
    EXPECT_EQ(hashes(dir / "d" / "manifest.json"), hashes(dir / "b" / "manifest.json"));
    EXPECT_EQ(hashes(manifest), hashes(dir / "b" / "manifest.json"));
}

std::string build_error(const std::filesystem::path& protocol, const std::filesystem::path& out);

// Every stimulus, clean or vocoded, gets the protocol's speech level
// ([corpus] level_dbfs, default -26 dBFS active-speech RMS); a level at which
// a stimulus would peak above -1 dBFS is refused at the key's line.
TEST_F(BuilderFixture, SetsEveryStimulusToTheSpeechLevelAndRefusesALevelThatClips) {
    build_stimuli(settings("a"));
    const auto manifest = nlohmann::json::parse(read_text_file(dir / "a" / "manifest.json"));
    EXPECT_EQ(manifest["settings"]["level"]["speech_dbfs"].get<double>(), -26.0);
    for (const auto& e : manifest["stimuli"]) {
        SCOPED_TRACE(e["path"].get<std::string>());
        const Audio audio = read_audio(dir / "a" / e["wav"].get<std::string>());
        const std::vector<double> x(audio.samples.begin(), audio.samples.end());
        const double rms = vocoder::speech_level_rms(x, audio.sample_rate_hz, vocoder::SnrReference::ActiveFrames);
        EXPECT_NEAR(20.0 * std::log10(rms), -26.0, 0.01);
        double peak = 0.0;
        for (const float v : audio.samples) peak = std::max(peak, double(std::fabs(v)));
        EXPECT_NEAR(e["level"]["peak_dbfs"].get<double>(), 20.0 * std::log10(peak), 0.01);
        EXPECT_LE(20.0 * std::log10(peak), -1.0);
        // The decoded AAC track keeps the level (lossy coding moves it a little).
        const DecodedVideo v = decode_video(dir / "a" / e["path"].get<std::string>());
        const std::vector<double> decoded(v.audio.samples.begin(), v.audio.samples.end());
        EXPECT_NEAR(20.0 * std::log10(vocoder::speech_level_rms(decoded, v.audio.sample_rate_hz,
                                                                 vocoder::SnrReference::ActiveFrames)),
                    -26.0, 0.5);
    }

    const std::filesystem::path data = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build";
    std::string text = read_text_file(data / "protocol.toml");
    const std::string voice = "voice = \"en-us\"\n";
    const auto at = text.find(voice);
    ASSERT_NE(at, std::string::npos);
    text.insert(at + voice.size(), "level_dbfs = -6\n");
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + std::ptrdiff_t(at + voice.size()), '\n'));
    const std::string rule = "../../../../protocols/models/rule.json";
    text.replace(text.find(rule), rule.size(),
                 (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").generic_string());
    std::filesystem::create_directories(dir / "loud");
    write_text_file(dir / "loud" / "protocol.toml", text);
    std::filesystem::copy_file(data / "corpus.csv", dir / "loud" / "corpus.csv");
    const std::string error = build_error(dir / "loud" / "protocol.toml", dir / "loud" / "out");
    EXPECT_NE(error.find("protocol.toml:" + std::to_string(line) + ":"), std::string::npos) << error;
    EXPECT_NE(error.find("corpus.level_dbfs"), std::string::npos) << error;
    EXPECT_NE(error.find("set level_dbfs to -"), std::string::npos) << error;
    EXPECT_FALSE(std::filesystem::exists(dir / "loud" / "out" / "manifest.json"));
}

// `build-stimuli --verify`: a fresh set verifies; a changed MP4, a missing
// WAV and a set without a manifest are reported.
TEST_F(BuilderFixture, VerifyChecksEveryStimulusAgainstTheManifest) {
    EXPECT_THROW(verify_stimuli(settings("a")), InputError);  // nothing built yet
    build_stimuli(settings("a"));
    const VerifyReport clean = verify_stimuli(settings("a"));
    EXPECT_EQ(clean.total, 6u);
    EXPECT_EQ(clean.verified, 6u);
    EXPECT_TRUE(clean.problems.empty()) << clean.problems.front();
    EXPECT_TRUE(clean.extra.empty());

    {
        std::ofstream mp4(dir / "a" / "s1" / "rule.mp4", std::ios::binary | std::ios::app);
        mp4 << '\0';
    }
    std::filesystem::remove(dir / "a" / "s2" / "blank.wav");
    const VerifyReport broken = verify_stimuli(settings("a"));
    EXPECT_EQ(broken.verified, 4u);
    ASSERT_EQ(broken.problems.size(), 2u);
    EXPECT_EQ(broken.problems[0], "s1/rule.mp4: the MP4 differs from the one built (SHA-256)");
    EXPECT_EQ(broken.problems[1], "s2/blank.mp4: the WAV s2/blank.wav is missing");

    // A smaller selection leaves the other entries as extra, not as problems.
    BuildSettings first = settings("a");
    first.max_sentences = 1;
    const VerifyReport part = verify_stimuli(first);
    EXPECT_EQ(part.total, 3u);
    EXPECT_EQ(part.extra, (std::vector<std::string>{"s2/audio-only.mp4", "s2/blank.mp4", "s2/rule.mp4"}));
}

// A closure hold declared as a factor: the model as trained beside its held
// variant. The manifest names each condition's policy, the held one's
// frames changed and mean change per parameter; both conditions' closure
// and contact rates are measured (the held one closes every /p b m/); the
// QC page lists each condition's worst segments; --verify passes.
TEST_F(BuilderFixture, RecordsEachConditionsPolicyAndWhatItsModelPutsOnTheLips) {
    const std::filesystem::path data = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build";
    std::filesystem::create_directories(dir / "p");
    std::filesystem::copy_file(data / "corpus.csv", dir / "p" / "corpus.csv");
    const std::string ohman = (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "ohman.json").string();
    write_text_file(dir / "p" / "protocol.toml",
                    "[experiment]\nname = \"policy\"\nseed = 7\n[corpus]\nsentences = \"corpus.csv\"\naudio = \"tts\"\n"
                    "voice = \"en-us\"\n[[condition]]\nname = \"ohman\"\nmodel = \"" + ohman + "\"\n"
                    "[[condition]]\nname = \"ohman+hold\"\nmodel = \"" + ohman + "\"\nclosure = \"hold\"\n"
                    "variant_of = \"ohman\"\n[vocoder]\nbands = 3\n[design]\nlists = 2\nsentences_per_list = 1\n"
                    "[render]\nfps = 30\nwidth = 160\nheight = 120\n");
    BuildSettings b = settings("policy");
    b.protocol_path = dir / "p" / "protocol.toml";
    build_stimuli(b);
    const auto manifest = nlohmann::json::parse(read_text_file(dir / "policy" / "manifest.json"));
    ASSERT_EQ(manifest["conditions"].size(), 2u);
    const auto& plain = manifest["conditions"][0];
    const auto& held = manifest["conditions"][1];
    EXPECT_EQ(plain["policy"]["closure"], "off");
    EXPECT_EQ(plain["policy"]["as_trained"], true);
    EXPECT_FALSE(plain.contains("closure_constraint"));
    EXPECT_EQ(held["policy"]["closure"], "hold");
    EXPECT_EQ(held["policy"]["variant_of"], "ohman");
    EXPECT_TRUE(held.contains("closure_constraint"));
    for (const auto* c : {&plain, &held}) {
        const auto& a = (*c)["articulation"];
        SCOPED_TRACE((*c)["name"].get<std::string>());
        EXPECT_EQ(a["stimuli"], 2u);
        EXPECT_GE(a["bilabials"].get<int>(), 2);  // "Bob", "bought"…
        EXPECT_GE(a["labiodentals"].get<int>(), 2);
        EXPECT_TRUE(a["closure_rate"].is_number());
        EXPECT_FALSE(a["worst_bilabials"].empty());
        EXPECT_EQ(a["failing_stimuli"], 0u);
    }
    EXPECT_EQ(held["articulation"]["bilabials_closed"], held["articulation"]["bilabials"]);
    EXPECT_EQ(held["articulation"]["labiodentals_reached"], held["articulation"]["labiodentals"]);
    const auto& change = held["articulation"]["closure_change"];
    EXPECT_EQ(change["segments_unmet"], 0u);
    EXPECT_GT(change["frames"].get<int>(), 0);
    for (const auto& [param, mean] : change["mean_abs_change"].items()) {
        EXPECT_TRUE(param == "jaw_rotation" || param == "upper_lip_raise" || param == "lower_lip_depression" ||
                    param == "lower_lip_retraction")
            << param << " changed by the closure constraint";
        EXPECT_GT(mean.get<double>(), 0.0);
    }
    for (const auto& e : manifest["stimuli"]) {
        EXPECT_EQ(e["policy"]["closure"], e["condition"] == "ohman" ? "off" : "hold");
        EXPECT_EQ(e.contains("closure_change"), e["condition"] == "ohman+hold");
    }
    const std::string qc = read_text_file(dir / "policy" / "qc" / "articulation.html");
    EXPECT_NE(qc.find("Worst segments per condition"), std::string::npos);
    EXPECT_NE(qc.find("closure hold (σ 25 ms), variant of ohman"), std::string::npos);
    EXPECT_NE(qc.find("<td>as trained</td>"), std::string::npos);
    // The methods paragraph states each condition's policy and what its model put on the lips.
    const std::string methods = read_text_file(dir / "policy" / "methods.md");
    EXPECT_NE(methods.find("- ohman: control model ohman.json (as trained), vocoded audio; measured on the rendered "
                           "face, the lips closed in"),
              std::string::npos)
        << methods;
    EXPECT_NE(methods.find("- ohman+hold: control model ohman.json (closure hold (σ 25 ms), variant of ohman)"),
              std::string::npos)
        << methods;
    EXPECT_NE(methods.find("was a factor of the design"), std::string::npos) << methods;
    EXPECT_NE(methods.find("- Channels: 3 analysis bands"), std::string::npos) << methods;
    const VerifyReport v = verify_stimuli(b);
    EXPECT_EQ(v.verified, 4u);
    EXPECT_TRUE(v.problems.empty()) << v.problems.front();
}

// With lists in the corpus, only what the design can show is built: test
// sentences in every condition, warm-up sentences in the warm-up condition,
// practice sentences in the practice condition, spare sentences not at all.
TEST_F(BuilderFixture, BuildsOnlyTheSentenceConditionPairsTheDesignShows) {
    const std::filesystem::path data = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build";
    std::string text = read_text_file(data / "protocol.toml");
    const auto replace = [&](const std::string& from, const std::string& to) {
        const auto at = text.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        text.replace(at, from.size(), to);
    };
    replace("model = \"../../../../protocols/models/rule.json\"",
            "model = \"" + (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").generic_string() + "\"");
    replace("warmup = 0\npractice = 0\n",
            "warmup = 1\nwarmup_condition = \"blank\"\npractice = 1\npractice_condition = \"rule\"\n");
    std::filesystem::create_directories(dir);
    write_text_file(dir / "protocol.toml", text);
    write_text_file(dir / "corpus.csv",
                    "id,text,keywords,list\n"
                    "s1,Bob wore a blue wool coat.,wore;blue;coat,1\n"
                    "w1,The sun is warm.,sun;warm;is,warmup\n"
                    "x1,A spare one here.,spare;one;here,\n"
                    "p1,We feed the fish.,feed;fish;we,practice\n");
    BuildSettings s = settings("out");
    s.protocol_path = dir / "protocol.toml";
    const BuildReport report = build_stimuli(s);
    EXPECT_EQ(report.total, 5u);
    EXPECT_EQ(report.not_needed, 7u);
    std::vector<std::string> paths;
    const auto manifest = nlohmann::json::parse(read_text_file(dir / "out" / "manifest.json"));
    for (const auto& e : manifest["stimuli"])
        paths.push_back(e["path"].get<std::string>());
    std::sort(paths.begin(), paths.end());
    EXPECT_EQ(paths, (std::vector<std::string>{"p1/rule.mp4", "s1/audio-only.mp4", "s1/blank.mp4", "s1/rule.mp4",
                                               "w1/blank.mp4"}));
}

// The message of the InputError a build throws, or "".
std::string build_error(const std::filesystem::path& protocol, const std::filesystem::path& out) {
    BuildSettings s;
    s.protocol_path = protocol;
    s.out_dir = out;
    try {
        build_stimuli(s);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

// A lab's own head: [render] head_mesh and head_rig, relative to the protocol
// file, here copies of the built-in head's files in a folder of their own.
TEST_F(BuilderFixture, BuildsWithTheHeadTheProtocolNames) {
    const std::filesystem::path data = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build";
    std::string text = read_text_file(data / "protocol.toml");
    const auto replace = [&](const std::string& from, const std::string& to) {
        const auto at = text.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        text.replace(at, from.size(), to);
    };
    replace("sentences = \"corpus.csv\"", "sentences = \"" + (data / "corpus.csv").generic_string() + "\"");
    replace("model = \"../../../../protocols/models/rule.json\"",
            "model = \"" + (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").generic_string() + "\"");
    std::filesystem::create_directories(dir / "lab" / "heads");
    std::filesystem::copy_file(default_head_obj(), dir / "lab" / "heads" / "head.obj");
    std::filesystem::copy_file(default_head_rig(), dir / "lab" / "heads" / "head.rig.json");
    std::filesystem::copy_file(default_head_obj().parent_path() / "head.png", dir / "lab" / "heads" / "head.png");
    write_text_file(dir / "lab" / "protocol.toml",
                    text + "head_mesh = \"heads/head.obj\"\nhead_rig = \"heads/head.rig.json\"\n");
    BuildSettings s = settings("own-head");
    s.protocol_path = dir / "lab" / "protocol.toml";
    s.max_sentences = 1;
    const BuildReport report = build_stimuli(s);
    EXPECT_EQ(report.rendered, 3u);
    const auto manifest = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    EXPECT_EQ(manifest["settings"]["head"]["mesh_sha256"], sha256_file(dir / "lab" / "heads" / "head.obj"));
    EXPECT_EQ(manifest["settings"]["head"]["rig_sha256"], sha256_file(dir / "lab" / "heads" / "head.rig.json"));
    EXPECT_EQ(manifest["settings"]["head"]["texture_sha256"], sha256_file(dir / "lab" / "heads" / "head.png"));
    for (const auto& e : manifest["stimuli"])
        EXPECT_EQ(decode_video(s.out_dir / e["path"].get<std::string>()).frame_count, e["frames"].get<std::size_t>());

    // A mesh without its rig, and a rig that is not there: refused at the key's line.
    const int last_line = static_cast<int>(std::count(text.begin(), text.end(), '\n')) + 1;
    write_text_file(dir / "lab" / "mesh-only.toml", text + "head_mesh = \"heads/head.obj\"\n");
    const std::string only = build_error(dir / "lab" / "mesh-only.toml", dir / "o1");
    EXPECT_NE(only.find("mesh-only.toml:" + std::to_string(last_line) + ":"), std::string::npos) << only;
    EXPECT_NE(only.find("head_mesh and head_rig together"), std::string::npos) << only;
    write_text_file(dir / "lab" / "missing.toml",
                    text + "head_mesh = \"heads/head.obj\"\nhead_rig = \"heads/nothing.rig.json\"\n");
    const std::string missing = build_error(dir / "lab" / "missing.toml", dir / "o2");
    EXPECT_NE(missing.find("missing.toml:" + std::to_string(last_line + 1) + ":"), std::string::npos) << missing;
    EXPECT_NE(missing.find("render.head_rig"), std::string::npos) << missing;
    EXPECT_NE(missing.find("nothing.rig.json"), std::string::npos) << missing;

    // A glTF head: the built-in one exported, named by head_gltf.
    export_gltf_head(test::default_head(), dir / "lab" / "heads" / "head.glb");
    write_text_file(dir / "lab" / "gltf.toml", text + "head_gltf = \"heads/head.glb\"\n");
    BuildSettings g = settings("gltf-head");
    g.protocol_path = dir / "lab" / "gltf.toml";
    g.max_sentences = 1;
    EXPECT_EQ(build_stimuli(g).rendered, 3u);
    const auto gm = nlohmann::json::parse(read_text_file(g.out_dir / "manifest.json"));
    EXPECT_EQ(gm["settings"]["head"]["gltf_sha256"], sha256_file(dir / "lab" / "heads" / "head.glb"));
    EXPECT_EQ(gm["settings"]["head"]["mapping_sha256"], sha256_file(default_blendshape_mapping()));
    write_text_file(dir / "lab" / "both.toml",
                    text + "head_gltf = \"heads/head.glb\"\nhead_mesh = \"heads/head.obj\"\nhead_rig = \"heads/head.rig.json\"\n");
    const std::string both = build_error(dir / "lab" / "both.toml", dir / "o3");
    EXPECT_NE(both.find("either head_gltf or head_mesh"), std::string::npos) << both;
}

// A copy of the test protocol with its [vocoder] section replaced, written
// to the fixture's folder with absolute corpus and model paths.
std::filesystem::path protocol_with_vocoder(const std::filesystem::path& dir, const std::string& vocoder) {
    const std::filesystem::path data = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build";
    std::string text = read_text_file(data / "protocol.toml");
    const auto replace = [&](const std::string& from, const std::string& to) {
        const auto at = text.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        text.replace(at, from.size(), to);
    };
    replace("sentences = \"corpus.csv\"", "sentences = \"" + (data / "corpus.csv").generic_string() + "\"");
    replace("model = \"../../../../protocols/models/rule.json\"",
            "model = \"" + (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").generic_string() + "\"");
    replace("[vocoder]\nbands = 3\nlow_hz = 100\nhigh_hz = 5000\n", "[vocoder]\n" + vocoder);
    std::filesystem::create_directories(dir);
    const auto path = dir / "protocol.toml";
    write_text_file(path, text);
    return path;
}

// A copy of the test protocol with its [corpus] voice line replaced.
std::filesystem::path protocol_with_voice(const std::filesystem::path& dir, const std::string& voice_line) {
    const std::filesystem::path data = std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build";
    std::string text = read_text_file(data / "protocol.toml");
    for (const auto& [from, to] :
         {std::pair<std::string, std::string>{"sentences = \"corpus.csv\"",
                                              "sentences = \"" + (data / "corpus.csv").generic_string() + "\""},
          {"model = \"../../../../protocols/models/rule.json\"",
           "model = \"" + (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").generic_string() + "\""},
          {"voice = \"en-us\"", voice_line}}) {
        const auto at = text.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        if (at != std::string::npos) text.replace(at, from.size(), to);
    }
    std::filesystem::create_directories(dir);
    const auto path = dir / "protocol.toml";
    write_text_file(path, text);
    return path;
}

// The voice and its version are in the manifest's settings and so in every
// stimulus's input hash: another voice rebuilds everything; a voice that is
// not installed is refused at the protocol's tts key, naming the installed ones.
TEST_F(BuilderFixture, RecordsTheVoiceAndRebuildsWhenItChanges) {
    BuildSettings s = settings("voice");
    s.max_sentences = 1;
    s.protocol_path = protocol_with_voice(dir / "slt", "tts = \"festival:cmu_us_slt_arctic_hts\"");
    EXPECT_EQ(build_stimuli(s).rendered, 3u);
    const auto slt = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    const auto& tts = slt["settings"]["tts"];
    EXPECT_EQ(tts["tts"], "festival:cmu_us_slt_arctic_hts");
    EXPECT_EQ(tts["engine"], "festival");
    EXPECT_EQ(tts["voice"], "cmu_us_slt_arctic_hts");
    EXPECT_EQ(tts["engine_version"].get<std::string>().rfind("2.", 0), 0u) << tts;
    EXPECT_EQ(tts["voice_sha256"].get<std::string>().size(), 64u);
    const Audio clean = read_audio(s.out_dir / slt["stimuli"][0]["wav"].get<std::string>());
    EXPECT_GT(clean.duration_s(), 1.0);
    EXPECT_EQ(build_stimuli(s).rendered, 0u);  // unchanged

    s.protocol_path = protocol_with_voice(dir / "kal", "tts = \"festival:kal_diphone\"");
    EXPECT_EQ(build_stimuli(s).rendered, 3u);
    const auto kal = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    EXPECT_EQ(kal["settings"]["tts"]["voice"], "kal_diphone");
    EXPECT_NE(kal["settings"]["tts"]["voice_sha256"], tts["voice_sha256"]);
    for (std::size_t i = 0; i < 3; ++i)
        EXPECT_NE(kal["stimuli"][i]["input_sha256"], slt["stimuli"][i]["input_sha256"]) << i;

    s.protocol_path = protocol_with_voice(dir / "bad", "tts = \"festival:cmu_us_slt\"");
    s.out_dir = dir / "bad-out";
    const std::string error = build_error(s.protocol_path, s.out_dir);
    EXPECT_NE(error.find(s.protocol_path.string() + ":11:7: error: corpus.tts: unknown Festival voice \"cmu_us_slt\""),
              std::string::npos)
        << error;
    EXPECT_NE(error.find("installed Festival voices: cmu_us_slt_arctic_hts"), std::string::npos) << error;
    EXPECT_FALSE(std::filesystem::exists(s.out_dir / "manifest.json"));
}

TEST_F(BuilderFixture, MapsEveryVocoderKeyOfTheProtocol) {
    const auto protocol = protocol_with_vocoder(dir,
                                                "bands = 4\nlow_hz = 150\nhigh_hz = 4000.0\nspacing = \"log\"\n"
                                                "filter_order = 3\nzero_phase = true\nenvelope = \"hilbert\"\n"
                                                "envelope_cutoff_hz = 50\nenvelope_filter_order = 2\n"
                                                "carrier = \"sine\"\nprefilter_carrier = true\n"
                                                "refilter_carrier = false\nlow_noise_iterations = 5\n"
                                                "match_band_rms = false\nmatch_output_rms = false\nseed = 99\n");
    BuildSettings s = settings("vocoder");
    s.protocol_path = protocol;
    s.max_sentences = 1;
    const BuildReport report = build_stimuli(s);
    EXPECT_EQ(report.rendered, 3u);
    const auto v = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"))["settings"]["vocoder"];
    EXPECT_EQ(v["bands"], 4);
    EXPECT_EQ(v["low_hz"], 150.0);
    EXPECT_EQ(v["high_hz"], 4000.0);
    EXPECT_EQ(v["spacing"], "log");
    EXPECT_EQ(v["filter_order"], 3);
    EXPECT_EQ(v["zero_phase"], true);
    EXPECT_EQ(v["envelope"], "hilbert");
    EXPECT_EQ(v["envelope_cutoff_hz"], 50.0);
    EXPECT_EQ(v["envelope_filter_order"], 2);
    EXPECT_EQ(v["carrier"], "sine");
    EXPECT_EQ(v["prefilter_carrier"], true);
    EXPECT_EQ(v["refilter_carrier"], false);
    EXPECT_EQ(v["low_noise_iterations"], 5);
    EXPECT_EQ(v["match_band_rms"], false);
    EXPECT_EQ(v["match_output_rms"], false);
    EXPECT_EQ(v["seed"], 99);

    // Explicit band edges.
    const auto explicit_edges = protocol_with_vocoder(
        dir / "edges", "bands = 2\nlow_hz = 100\nhigh_hz = 4000\nspacing = \"explicit\"\nedges_hz = [100, 900, 4000]\n");
    BuildSettings e = settings("edges-out");
    e.protocol_path = explicit_edges;
    e.max_sentences = 1;
    build_stimuli(e);
    const auto ve = nlohmann::json::parse(read_text_file(e.out_dir / "manifest.json"))["settings"]["vocoder"];
    EXPECT_EQ(ve["edges_hz"], nlohmann::json({100.0, 900.0, 4000.0}));
}

TEST_F(BuilderFixture, RefusesUnknownAndInconsistentVocoderKeysWithTheirLocation) {
    // The [vocoder] section is on line 29 of the test protocol; its keys follow.
    const std::string typo = build_error(protocol_with_vocoder(dir / "typo", "bnads = 4\ncarrier = \"sin\"\n"), dir / "o1");
    EXPECT_NE(typo.find("protocol.toml:30:"), std::string::npos) << typo;
    EXPECT_NE(typo.find("did you mean \"bands\""), std::string::npos) << typo;
    EXPECT_NE(typo.find("protocol.toml:31:"), std::string::npos) << typo;
    EXPECT_NE(typo.find("did you mean \"sine\""), std::string::npos) << typo;

    const std::string edges =
        build_error(protocol_with_vocoder(dir / "edges", "bands = 3\nspacing = \"explicit\"\nedges_hz = [100, 900, 5000]\n"),
                    dir / "o2");
    EXPECT_NE(edges.find("protocol.toml:32:"), std::string::npos) << edges;
    EXPECT_NE(edges.find("edges_hz"), std::string::npos) << edges;

    const std::string type = build_error(protocol_with_vocoder(dir / "type", "zero_phase = \"yes\"\n"), dir / "o3");
    EXPECT_NE(type.find("protocol.toml:30:"), std::string::npos) << type;
    EXPECT_NE(type.find("zero_phase"), std::string::npos) << type;
}

// A condition with its own [condition.vocoder] (a pulse-train CI simulation
// beside [vocoder]'s noise carrier): its settings in the condition's manifest
// record and its stimuli's input hash, its paragraph in methods.md, and audio
// unlike the other vocoded condition's; the plain condition keeps its hash.
TEST_F(BuilderFixture, AConditionsOwnVocoderIsAppliedRecordedAndDescribed) {
    const auto plain = protocol_with_vocoder(dir / "plain", "bands = 3\nlow_hz = 100\nhigh_hz = 5000\n");
    BuildSettings a = settings("plain-out");
    a.protocol_path = plain;
    a.max_sentences = 1;
    build_stimuli(a);
    std::string text = read_text_file(plain);
    const std::string blank = "name = \"blank\"\nface = \"none\"\naudio = \"vocoded\"\n";
    ASSERT_NE(text.find(blank), std::string::npos);
    text.replace(text.find(blank), blank.size(),
                 blank + "[condition.vocoder]\ncarrier = \"pulse-train\"\nbands = 8\nn_of_m = 4\n"
                         "current_spread = \"db-per-octave\"\nspread_slope_db = 6\ninsertion_shift_mm = 2\n");
    std::filesystem::create_directories(dir / "own");
    write_text_file(dir / "own" / "protocol.toml", text);
    BuildSettings b = settings("own-out");
    b.protocol_path = dir / "own" / "protocol.toml";
    b.max_sentences = 1;
    build_stimuli(b);
    const auto ma = nlohmann::json::parse(read_text_file(a.out_dir / "manifest.json"));
    const auto mb = nlohmann::json::parse(read_text_file(b.out_dir / "manifest.json"));
    const auto entry = [](const nlohmann::json& m, const std::string& condition) {
        for (const auto& e : m["stimuli"])
            if (e["condition"] == condition) return e;
        return nlohmann::json();
    };
    EXPECT_EQ(entry(ma, "rule")["input_sha256"], entry(mb, "rule")["input_sha256"]);
    EXPECT_NE(entry(ma, "blank")["input_sha256"], entry(mb, "blank")["input_sha256"]);
    nlohmann::json own;
    for (const auto& c : mb["conditions"])
        if (c["name"] == "blank") own = c["vocoder"];
    EXPECT_EQ(own["carrier"], "pulse-train");
    EXPECT_EQ(own["bands"], 8);
    EXPECT_EQ(own["n_of_m"], 4);
    EXPECT_EQ(own["current_spread"], "db-per-octave");
    EXPECT_EQ(own["insertion_shift_mm"], 2.0);
    EXPECT_EQ(own["carrier_edges_hz"].size(), 9u);
    EXPECT_EQ(mb["settings"]["vocoder"]["carrier"], "noise");
    const std::string methods = read_text_file(b.out_dir / "methods.md");
    EXPECT_NE(methods.find("Audio of the vocoded conditions:"), std::string::npos) << methods;
    EXPECT_NE(methods.find("Audio of condition blank (its own vocoder):"), std::string::npos) << methods;
    EXPECT_NE(methods.find("- Channel selection: 4-of-8"), std::string::npos) << methods;
    EXPECT_EQ(mb["methods"], methods) << "the manifest carries the methods paragraph";
    const Audio rule = read_audio(b.out_dir / entry(mb, "rule")["wav"].get<std::string>());
    const Audio pulses = read_audio(b.out_dir / entry(mb, "blank")["wav"].get<std::string>());
    EXPECT_NE(rule.samples, pulses.samples);

    // An impossible setting of the condition's table is refused at its line.
    const std::string bad = text.replace(text.find("n_of_m = 4"), 10, "n_of_m = 9");
    write_text_file(dir / "own" / "bad.toml", bad);
    const std::string error = build_error(dir / "own" / "bad.toml", dir / "o-bad");
    EXPECT_NE(error.find("bad.toml:"), std::string::npos) << error;
    EXPECT_NE(error.find("vocoder.n_of_m: expected 0 (every channel) or at most the 8 bands, got 9"),
              std::string::npos)
        << error;
}

}  // namespace
}  // namespace avsi::stimuli

namespace avsi::stimuli {

// A band-count adaptive protocol ([adaptive] variable = "bands"): the builder
// pre-renders each vocoded stimulus's audio at every level beside the MP4,
// lists the files with their SHA-256 in the manifest, and --verify checks
// them. The variant at the protocol's own band count is the stimulus's WAV
// sample for sample (the same vocoder and seed).
TEST_F(BuilderFixture, BandCountTracksGetAnAudioVariantPerLevelListedAndVerified) {
    auto protocol = protocol_with_vocoder(dir / "p", "bands = 3\nlow_hz = 100\nhigh_hz = 5000\n");
    std::string text = read_text_file(protocol);
    const auto clean = text.find("[[condition]]\nname = \"audio-only\"");
    ASSERT_NE(clean, std::string::npos);
    text.erase(clean, text.find("[[condition]]", clean + 1) - clean);  // every condition vocoded
    text.replace(text.find("lists = 3"), 9, "lists = 2");
    text += "\n[adaptive]\nvariable = \"bands\"\nlevels = [2, 3, 6]\nsrt_from = 1\n";
    write_text_file(protocol, text);
    BuildSettings s = settings("bands");
    s.protocol_path = protocol;
    s.max_sentences = 1;
    const BuildReport report = build_stimuli(s);
    ASSERT_EQ(report.rendered, 2u);
    const auto manifest = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    int files = 0;
    for (const auto& e : manifest["stimuli"]) {
        SCOPED_TRACE(e["path"].get<std::string>());
        const auto& v = e["variants"];
        ASSERT_TRUE(v.is_object());
        EXPECT_EQ(v["variable"], "bands");
        EXPECT_EQ(v["unit"], "bands");
        ASSERT_EQ(v["files"].size(), 3u);
        const Audio main = read_audio(s.out_dir / e["wav"].get<std::string>());
        std::vector<std::vector<float>> rendered;
        for (const auto& f : v["files"]) {
            const std::string wav = f["wav"].get<std::string>();
            EXPECT_EQ(wav, variant_audio_path(e["path"].get<std::string>(), "bands", f["level"].get<double>())
                               .generic_string());
            EXPECT_EQ(sha256_file(s.out_dir / wav), f["sha256"].get<std::string>());
            const Audio a = read_audio(s.out_dir / wav);
            EXPECT_EQ(a.sample_rate_hz, main.sample_rate_hz);
            EXPECT_EQ(a.samples.size(), main.samples.size());
            if (f["level"].get<double>() == 3.0) {
                EXPECT_EQ(a.samples, main.samples);
            }
            rendered.push_back(a.samples);
            ++files;
        }
        EXPECT_NE(rendered[0], rendered[1]);
        EXPECT_NE(rendered[1], rendered[2]);
    }
    EXPECT_EQ(files, 6);
    EXPECT_EQ(build_stimuli(s).rendered, 0u);  // unchanged: nothing rebuilt
    const VerifyReport ok = verify_stimuli(s);
    EXPECT_EQ(ok.verified, 2u);
    EXPECT_TRUE(ok.problems.empty());
    // A changed variant and a missing one are found.
    const auto& first = manifest["stimuli"][0];
    const std::string changed = first["variants"]["files"][0]["wav"], missing = first["variants"]["files"][2]["wav"];
    Audio a = read_audio(s.out_dir / changed);
    a.samples[100] += 0.01f;
    write_audio(s.out_dir / changed, a);
    std::filesystem::remove(s.out_dir / missing);
    const VerifyReport broken = verify_stimuli(s);
    EXPECT_EQ(broken.verified, 1u);
    std::string all;
    for (const auto& p : broken.problems) all += p + "\n";
    EXPECT_NE(all.find("the variant " + changed + " differs from the one built"), std::string::npos) << all;
    EXPECT_NE(all.find("the variant " + missing + " is missing"), std::string::npos) << all;
    // Other levels: the stimuli are out of date and rebuilt.
    write_text_file(protocol, text.substr(0, text.find("levels = [2, 3, 6]")) + "levels = [2, 4]\nsrt_from = 1\n");
    EXPECT_EQ(build_stimuli(s).rendered, 2u);
}

// An SNR track with the masker before vocoding (noise_stage = "before", the
// default): each vocoded stimulus gets its speech before the vocoder beside
// the MP4 (the clean condition's audio, sample for sample), listed with its
// SHA-256 and verified; with noise_stage = "after" there is none, and the
// stimuli are rebuilt (their inputs changed).
TEST_F(BuilderFixture, SnrTracksWithNoiseBeforeVocodingGetTheUnvocodedSpeech) {
    auto protocol = protocol_with_vocoder(dir / "p", "bands = 3\nlow_hz = 100\nhigh_hz = 5000\n");
    const std::string text = read_text_file(protocol);
    ASSERT_NE(text.find("name = \"audio-only\""), std::string::npos);
    const std::string adaptive = "\n[adaptive]\nsrt_from = 1\n";
    write_text_file(protocol, text + adaptive);
    BuildSettings s = settings("unvocoded");
    s.protocol_path = protocol;
    s.max_sentences = 1;
    s.all_sentences = true;
    const BuildReport report = build_stimuli(s);
    ASSERT_GE(report.rendered, 2u);
    const auto manifest = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    std::map<std::string, std::vector<float>> clean_audio;  // sentence → its clean condition's audio
    for (const auto& e : manifest["stimuli"])
        if (e["audio"] == "clean")
            clean_audio[e["sentence"].get<std::string>()] = read_audio(s.out_dir / e["wav"].get<std::string>()).samples;
    int vocoded = 0;
    for (const auto& e : manifest["stimuli"]) {
        SCOPED_TRACE(e["path"].get<std::string>());
        if (e["audio"] != "vocoded") {
            EXPECT_FALSE(e.contains("unvocoded"));
            continue;
        }
        ASSERT_TRUE(e.contains("unvocoded"));
        const std::string wav = e["unvocoded"]["wav"].get<std::string>();
        EXPECT_EQ(wav, unvocoded_audio_path(e["path"].get<std::string>()).generic_string());
        EXPECT_EQ(sha256_file(s.out_dir / wav), e["unvocoded"]["sha256"].get<std::string>());
        const Audio u = read_audio(s.out_dir / wav);
        const Audio v = read_audio(s.out_dir / e["wav"].get<std::string>());
        EXPECT_EQ(u.sample_rate_hz, v.sample_rate_hz);
        EXPECT_EQ(u.samples.size(), v.samples.size());
        EXPECT_NE(u.samples, v.samples);
        const auto c = clean_audio.find(e["sentence"].get<std::string>());
        if (c != clean_audio.end()) {
            EXPECT_EQ(u.samples, c->second);
        }
        ++vocoded;
    }
    ASSERT_GT(vocoded, 0);
    EXPECT_EQ(verify_stimuli(s).problems.size(), 0u);
    // A changed unvocoded file is found.
    const std::string first = [&] {
        for (const auto& e : manifest["stimuli"])
            if (e.contains("unvocoded")) return e["unvocoded"]["wav"].get<std::string>();
        return std::string();
    }();
    Audio a = read_audio(s.out_dir / first);
    a.samples[100] += 0.01f;
    write_audio(s.out_dir / first, a);
    std::string all;
    for (const auto& p : verify_stimuli(s).problems) all += p + "\n";
    EXPECT_NE(all.find("the unvocoded speech " + first + " differs from the one built"), std::string::npos) << all;
    // Noise after vocoding: no unvocoded speech, and the vocoded stimuli are out of date.
    write_text_file(protocol, text + adaptive + "noise_stage = \"after\"\n");
    EXPECT_EQ(build_stimuli(s).rendered, static_cast<std::size_t>(vocoded));
    const auto after = nlohmann::json::parse(read_text_file(s.out_dir / "manifest.json"));
    for (const auto& e : after["stimuli"]) EXPECT_FALSE(e.contains("unvocoded"));
}

}  // namespace avsi::stimuli
