#include "avsi/core/protocol.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

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

// [corpus] tts = "<engine>:<voice>" (or the older voice = "<espeak-ng voice>"):
// read into engine and voice; mistakes reported at the key.
TEST(Protocol, TtsKeyNamesEngineAndVoice) {
    const fs::path dir = test::temp_dir("protocol_tts");
    fs::copy_file(data_dir / "corpus.csv", dir / "corpus.csv", fs::copy_options::overwrite_existing);
    const auto load = [&](const std::string& corpus_keys) {
        write_text_file(dir / "p.toml", "[experiment]\nname = \"t\"\n\n[corpus]\nsentences = \"corpus.csv\"\n" +
                                            corpus_keys + "\n[[condition]]\nname = \"a\"\n");
        return load_protocol(dir / "p.toml");
    };
    const auto error = [&](const std::string& corpus_keys) -> std::string {
        try {
            (void)load(corpus_keys);
        } catch (const InputError& e) {
            return e.what();
        }
        return "(no error)";
    };
    Protocol p = load("tts = \"festival:cmu_us_slt_arctic_hts\"\n");
    EXPECT_EQ(p.corpus.tts_engine, TtsEngine::Festival);
    EXPECT_EQ(p.corpus.tts_voice, "cmu_us_slt_arctic_hts");
    EXPECT_EQ(p.corpus.tts_line, 6);
    EXPECT_EQ(p.corpus.tts_column, 7);
    p = load("tts = \"espeak:en-gb-x-rp\"\n");
    EXPECT_EQ(p.corpus.tts_engine, TtsEngine::Espeak);
    EXPECT_EQ(p.corpus.tts_voice, "en-gb-x-rp");
    p = load("");  // the default
    EXPECT_EQ(p.corpus.tts_engine, TtsEngine::Espeak);
    EXPECT_EQ(p.corpus.tts_voice, "en-us");
    EXPECT_EQ(p.corpus.tts_line, 0);
    const std::string file = (dir / "p.toml").string();
    EXPECT_EQ(error("tts = \"mary:slt\"\n"),
              file + ":6:7: error: corpus.tts: expected \"espeak:<voice>\" or \"festival:<voice>\" (e.g. "
                     "\"espeak:en-us\", \"festival:cmu_us_slt_arctic_hts\"), got \"mary:slt\"");
    EXPECT_EQ(error("tts = \"festival:\"\n"),
              file + ":6:7: error: corpus.tts: expected a voice name after \"festival:\", got \"festival:\"");
    EXPECT_EQ(error("tts = \"festival:kal_diphone\"\nvoice = \"en-us\"\n"),
              file + ":7:9: error: corpus.voice: expected either tts or voice, got both (voice = \"en-us\" is the "
                     "older spelling of tts = \"espeak:en-us\"); remove voice");
    EXPECT_EQ(error("voice = \"festival:kal_diphone\"\n"),
              file + ":6:9: error: corpus.voice: expected an espeak-ng voice name (en-us, en, ...), got "
                     "\"festival:kal_diphone\" (did you mean tts = \"festival:kal_diphone\"?)");
    EXPECT_EQ(error("tts = 3\n"), file + ":6:7: error: corpus.tts: expected a string, got 3");
    fs::remove_all(dir);
}

// [corpus] language: the voice's by default, or named; a language other than
// the voice's, or one without a table, is refused at the key.
TEST(Protocol, LanguageComesFromTheVoiceOrTheCorpusKey) {
    const fs::path dir = test::temp_dir("protocol_language");
    fs::copy_file(data_dir / "corpus.csv", dir / "corpus.csv", fs::copy_options::overwrite_existing);
    const auto load = [&](const std::string& corpus_keys) {
        write_text_file(dir / "p.toml", "[experiment]\nname = \"t\"\n\n[corpus]\nsentences = \"corpus.csv\"\n" +
                                            corpus_keys + "\n[[condition]]\nname = \"a\"\n");
        return load_protocol(dir / "p.toml");
    };
    const auto error = [&](const std::string& corpus_keys) -> std::string {
        try {
            (void)load(corpus_keys);
        } catch (const InputError& e) {
            return e.what();
        }
        return "(no error)";
    };
    EXPECT_EQ(load("").corpus.language, "en");
    EXPECT_EQ(load("tts = \"espeak:sv\"\n").corpus.language, "sv");
    EXPECT_EQ(load("tts = \"espeak:de\"\n").corpus.language, "de");
    EXPECT_EQ(load("tts = \"festival:cmu_us_slt_arctic_hts\"\n").corpus.language, "en");
    EXPECT_EQ(load("tts = \"espeak:sv\"\nlanguage = \"sv\"\n").corpus.language, "sv");
    const std::string file = (dir / "p.toml").string();
    EXPECT_EQ(error("tts = \"espeak:sv\"\nlanguage = \"de\"\n"),
              file + ":7:12: error: corpus.language: expected the voice's language \"sv\" (tts = \"espeak:sv\"), got \"de\"");
    EXPECT_EQ(error("language = \"fr\"\n"),
              file + ":6:12: error: corpus.language: expected \"de\", \"en\", or \"sv\", got \"fr\" (did you mean \"de\"?)");
    // Recordings with no voice named: the key says the language; synthesised
    // speech in the default voice cannot be Swedish.
    EXPECT_EQ(load("audio = \"recordings\"\nlanguage = \"sv\"\n").corpus.language, "sv");
    EXPECT_EQ(load("audio = \"recordings\"\nlanguage = \"sv\"\n").session.language, "sv");
    EXPECT_EQ(error("language = \"sv\"\n"),
              file + ":6:12: error: corpus.language: expected the default voice's language \"en\" (espeak:en-us), "
                     "got \"sv\": the sentences are synthesised, so name a voice of it in tts (tts = \"espeak:sv\")");
    EXPECT_EQ(error("audio = \"recordings\"\ntts = \"espeak:de\"\nlanguage = \"sv\"\n"),
              file + ":8:12: error: corpus.language: expected the voice's language \"de\" (tts = \"espeak:de\"), got "
                     "\"sv\"");
    // One language per protocol: what the subject reads is the corpus's.
    EXPECT_EQ(load("tts = \"espeak:sv+m3\"\n").corpus.language, "sv");
    EXPECT_EQ(load("tts = \"espeak:sv+m3\"\n").session.language, "sv");
    EXPECT_EQ(load("tts = \"espeak:de\"\nlanguage = \"de\"\n").session.language, "de");
    EXPECT_EQ(error("tts = \"festival:cmu_us_slt_arctic_hts\"\nlanguage = \"sv\"\n"),
              file + ":7:12: error: corpus.language: expected the voice's language \"en\" (tts = "
                     "\"festival:cmu_us_slt_arctic_hts\"), got \"sv\"");
    EXPECT_EQ(error("tts = \"espeak:fr\"\n"),
              file + ":6:7: error: corpus.tts: voice \"fr\" speaks no language with tables in protocols/languages/ "
                     "(de, en, sv): no phones, scoring or texts of what the subject reads for it");
    fs::remove_all(dir);
}

TEST(Protocol, GoldenErrorBadTypes) { check_golden("bad_types"); }
TEST(Protocol, GoldenErrorUnknownKeys) { check_golden("unknown_keys"); }
TEST(Protocol, GoldenErrorReferences) { check_golden("references"); }
TEST(Protocol, GoldenErrorSyntax) { check_golden("syntax"); }

TEST(Protocol, GoldenErrorScoring) { check_golden("scoring"); }
TEST(Protocol, GoldenErrorPolicyOnSomeModelConditions) { check_golden("policy"); }
TEST(Protocol, GoldenErrorPolicyVariants) { check_golden("policy_variants"); }

// The fair-comparison rule: one policy over every model condition, or the
// policy declared as a factor (a held variant beside the model as trained).
TEST(Protocol, ClosurePolicyAppliesToEveryModelConditionOrIsADeclaredFactor) {
    const std::string head = "[experiment]\nname = \"p\"\n[corpus]\nsentences = \"corpus.csv\"\n"
                             "[[condition]]\nname = \"audio-only\"\n";
    const auto model = [](const std::string& name, const std::string& file, const std::string& extra) {
        return "[[condition]]\nname = \"" + name + "\"\nmodel = \"models/" + file + "\"\n" + extra;
    };
    const fs::path path = data_dir / "inline.toml";
    // As trained everywhere, and held everywhere: both fine.
    EXPECT_NO_THROW(parse_protocol(head + model("cm", "cm.json", "") + model("ann2", "ann2.json", ""), path));
    EXPECT_NO_THROW(parse_protocol(head + model("cm", "cm.json", "closure = \"hold\"\n") +
                                       model("ann2", "ann2.json", "closure = \"hold\"\n"),
                                   path));
    // Held on one of two: refused, naming both.
    try {
        parse_protocol(head + model("cm", "cm.json", "") + model("ann2", "ann2.json", "closure = \"hold\"\n"), path);
        ADD_FAILURE() << "a hold on a subset of the model conditions was accepted";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("inline.toml:13:"), std::string::npos) << what;  // at ann2's closure key
        EXPECT_NE(what.find("on ann2"), std::string::npos) << what;
        EXPECT_NE(what.find("on cm"), std::string::npos) << what;
        EXPECT_NE(what.find("variant_of = \"ann2\""), std::string::npos) << what;
    }
    // The same hold declared as a factor: accepted, and the variant named.
    const Protocol p = parse_protocol(head + model("cm", "cm.json", "") + model("ann2", "ann2.json", "") +
                                          model("ann2+hold", "ann2.json", "closure = \"hold\"\nvariant_of = \"ann2\"\n"),
                                      path);
    ASSERT_EQ(p.conditions.size(), 4u);
    EXPECT_TRUE(p.conditions[3].closure_hold);
    EXPECT_EQ(p.conditions[3].variant_of, "ann2");
    EXPECT_TRUE(p.conditions[2].variant_of.empty());
}

TEST(Protocol, ScoringRuleSetAndHomophoneTable) {
    EXPECT_EQ(load_protocol(data_dir / "valid.toml").scoring.rules, "strict");  // the default
    EXPECT_TRUE(load_protocol(data_dir / "valid.toml").scoring.homophones.empty());
    const std::string text = "[experiment]\nname = \"s\"\n[corpus]\nsentences = \"corpus.csv\"\n"
                             "[[condition]]\nname = \"a\"\n[scoring]\nrules = \"lenient\"\n"
                             "homophones = \"corpus.csv\"\n";
    const Protocol p = parse_protocol(text, data_dir / "inline.toml");
    EXPECT_EQ(p.scoring.rules, "lenient");
    EXPECT_EQ(p.scoring.homophones, data_dir / "corpus.csv");
    EXPECT_EQ(protocol_rule_sets(), (std::vector<std::string>{"strict", "loose", "lenient"}));
    // The shipped default protocol names its rule set.
    EXPECT_EQ(load_protocol(fs::path(AVSI_PROTOCOLS_DIR) / "beskow2004-en.toml").scoring.rules, "strict");
}

TEST(Protocol, MissingFileIsAnInputError) {
    EXPECT_THROW(load_protocol(data_dir / "does-not-exist.toml"), InputError);
}

}  // namespace
}  // namespace avsi
