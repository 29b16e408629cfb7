#include "avsi/core/protocol.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

const fs::path data_dir = fs::path(AVSI_TEST_DATA_DIR) / "protocols";

// The error text with the test-data folder prefix removed, so golden files
// hold "protocols/x.toml:3:9: error: …".
std::string error_output(const fs::path& protocol) {
    try {
        load_protocol(protocol);
    } catch (const InputError& e) {
        std::string text = std::string(e.what()) + "\n";
        const std::string prefix = std::string(AVSI_TEST_DATA_DIR) + "/";
        for (std::size_t at; (at = text.find(prefix)) != std::string::npos;) text.erase(at, prefix.size());
        return text;
    }
    return "(no error)\n";
}

void check_golden(const std::string& name) {
    SCOPED_TRACE(name);
    const fs::path golden = data_dir / (name + ".err");
    const std::string actual = error_output(data_dir / (name + ".toml"));
    if (std::getenv("AVSI_UPDATE_GOLDEN")) {
        write_text_file(golden, actual);
        return;
    }
    ASSERT_TRUE(fs::exists(golden)) << "missing " << golden << "; run with AVSI_UPDATE_GOLDEN=1";
    EXPECT_EQ(actual, read_text_file(golden));
}

TEST(Protocol, LoadsAValidProtocol) {
    const Protocol p = load_protocol(data_dir / "valid.toml");
    EXPECT_EQ(p.name, "test-study");
    EXPECT_EQ(p.seed, 42u);
    EXPECT_EQ(p.corpus.sentences, data_dir / "corpus.csv");
    EXPECT_EQ(p.corpus.tts_engine, TtsEngine::Espeak);
    EXPECT_EQ(p.corpus.tts_voice, "en-gb");
    ASSERT_EQ(p.conditions.size(), 2u);
    EXPECT_EQ(p.conditions[0].face, FaceMode::Still);
    EXPECT_TRUE(p.conditions[0].model.empty());
    EXPECT_EQ(p.conditions[1].face, FaceMode::Model);
    EXPECT_EQ(p.conditions[1].model, data_dir / "models/cm.json");
    EXPECT_EQ(p.design.lists, 2);
    EXPECT_EQ(p.design.counterbalance, Counterbalance::Williams);
    EXPECT_EQ(p.design.seed, 42u);
    EXPECT_EQ(p.design.warmup_condition, "audio-only");
    EXPECT_EQ(p.render.width, 320);
    EXPECT_FALSE(p.session.fullscreen);
    EXPECT_EQ(p.session.break_every, 10);
    EXPECT_EQ(p.session.instructions, "Repeat what you hear.");
    EXPECT_TRUE(p.vocoder.present());
    DiagnosticList problems;
    EXPECT_EQ(p.vocoder.get_int("bands", 0, 1, 32, problems), 3);
    EXPECT_EQ(p.vocoder.find("bands")->line, 21);
    EXPECT_EQ(p.condition_index("cohen-massaro"), 1);
}

TEST(Protocol, GoldenErrorBadTypes) { check_golden("bad_types"); }
TEST(Protocol, GoldenErrorUnknownKeys) { check_golden("unknown_keys"); }
TEST(Protocol, GoldenErrorReferences) { check_golden("references"); }
TEST(Protocol, GoldenErrorSyntax) { check_golden("syntax"); }

TEST(Protocol, MissingFileIsAnInputError) {
    EXPECT_THROW(load_protocol(data_dir / "does-not-exist.toml"), InputError);
}

}  // namespace
}  // namespace avsi
