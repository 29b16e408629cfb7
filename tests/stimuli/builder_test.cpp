// The stimulus-set builder on a minimal protocol: every stimulus decodes to
// its manifest frame count, a rebuild renders nothing and gives the same
// manifest hashes, and a fresh build elsewhere gives identical hashes.
#include <unistd.h>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "avsi/core/files.h"
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/video.h"

namespace avsi::stimuli {
namespace {

struct BuilderFixture : ::testing::Test {
    std::filesystem::path dir = std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_avsi_builder_test");
    void SetUp() override { std::filesystem::remove_all(dir); }
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
        for (const auto& e : nlohmann::json::parse(read_text_file(manifest))["stimuli"])
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

    const BuildReport second = build_stimuli(settings("a"));
    EXPECT_EQ(second.rendered, 0u);
    EXPECT_EQ(second.skipped, 6u);
    EXPECT_EQ(hashes(manifest), hashes(dir / "a" / "manifest.json"));

    build_stimuli(settings("b"));
    EXPECT_EQ(hashes(manifest), hashes(dir / "b" / "manifest.json"));
}

}  // namespace
}  // namespace avsi::stimuli
