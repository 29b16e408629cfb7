// What the subject reads, per language (core/ui_strings.h): every table has
// the English keys and placeholders, the English [session] texts are the
// texts the protocol had before the table (so English sessions and web
// studies are unchanged), a Swedish protocol's session texts come from the
// Swedish table, and a table with a missing key or a lost placeholder is
// refused naming the file and the key.
#include <filesystem>

#include <gtest/gtest.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/protocol.h"
#include "avsi/core/ui_strings.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

TEST(UiStrings, EveryLanguageHasTheEnglishKeys) {
    for (const char* language : {"en", "sv", "de"}) {
        SCOPED_TRACE(language);
        const UiStrings& s = ui_strings(language);
        EXPECT_FALSE(s.text("runner", "answer_prompt").empty());
        EXPECT_EQ(s.fill("runner", "progress", {{"position", "3"}, {"total", "90"}}).find('{'), std::string::npos);
    }
    EXPECT_EQ(ui_strings("sv").fill("runner", "progress", {{"position", "3"}, {"total", "90"}}), "Mening 3 av 90");
    EXPECT_EQ(ui_strings("de").fill("runner", "progress", {{"position", "3"}, {"total", "90"}}), "Satz 3 von 90");
    EXPECT_EQ(ui_strings("en").fill("runner", "progress", {{"position", "3"}, {"total", "90"}}), "Sentence 3 of 90");
}

TEST(UiStrings, EnglishSessionTextsAreTheFormerDefaults) {
    const SessionSettings former;  // the defaults written in protocol.h
    const UiStrings& en = ui_strings("en");
    EXPECT_EQ(en.text("session", "instructions"), former.instructions);
    EXPECT_EQ(en.text("session", "practice_instructions"), former.practice_instructions);
    EXPECT_EQ(en.text("session", "test_instructions"), former.test_instructions);
    EXPECT_EQ(en.text("session", "break_text"), former.break_text);
    EXPECT_EQ(en.text("session", "end_text"), former.end_text);
}

TEST(UiStrings, ProtocolTextsComeFromTheLanguageOfTheVoice) {
    const Protocol sv = load_protocol(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "beskow2004-sv.toml");
    EXPECT_EQ(sv.session.language, "sv");
    EXPECT_EQ(sv.session.test_instructions, "Nu börjar testet. Texten visas inte längre.");
    const Protocol en = load_protocol(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "beskow2004-en.toml");
    EXPECT_EQ(en.session.language, "en");
    EXPECT_EQ(en.session.end_text, SessionSettings{}.end_text);
}

TEST(UiStrings, ATableMissingAKeyOrAPlaceholderIsRefused) {
    const auto dir = test::temp_dir("ui_strings_test");
    std::string text = read_text_file(ui_strings_file("sv"));
    const auto without_progress = text.substr(0, text.find("progress ="));
    write_text_file(dir / "missing.toml", without_progress);
    try {
        (void)UiStrings::read(dir / "missing.toml", "xx");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("missing.toml"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("runner.progress"), std::string::npos) << e.what();
    }
    std::string lost = text;
    lost.replace(lost.find("{total}"), 7, "alla");
    write_text_file(dir / "lost.toml", lost);
    try {
        (void)UiStrings::read(dir / "lost.toml", "xx");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("placeholders"), std::string::npos) << e.what();
    }
    std::filesystem::remove_all(dir);
}

TEST(UiStrings, AVoiceOfALanguageWithoutATableIsRefusedAtItsLine) {
    const std::string text =
        "[experiment]\nname = \"x\"\n[corpus]\nsentences = \"" +
        (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "sentences.csv").string() +
        "\"\ntts = \"espeak:fr\"\n[[condition]]\nname = \"audio-only\"\nface = \"still\"\n[design]\nlists = 1\n";
    try {
        (void)parse_protocol(text, "/tmp/fr.toml");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("/tmp/fr.toml:5:7: error: corpus.tts: voice \"fr\" speaks no language "
                                             "with tables in protocols/languages/ (de, en, sv)"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace avsi
