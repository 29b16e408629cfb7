// `avsi phones` end to end: text and label-file inputs, exit codes 0/1/2, and
// compiler-style error messages for malformed label files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/phones.h"
#include "avsi/core/tts.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

using RunResult = test::CliResult;

const fs::path data_dir = fs::path(AVSI_TEST_DATA_DIR) / "core";

// The folder of this process's tests (ctest runs each test in a process of its own).
fs::path work_dir() {
    static const fs::path dir = test::temp_dir("e2e_phones");
    return dir;
}

std::string quote(const std::string& s) { return test::shell_quote(s); }

using test::run_avsi;

TEST(PhonesCli, TextGivesWavAndContiguousPhonesCoveringIt) {
    const fs::path dir = work_dir();
    const RunResult r = run_avsi("phones --text 'Come here John.' --wav " + quote((dir / "s.wav").string()) +
                                 " --out " + quote((dir / "s.tsv").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out, "");
    const Audio audio = read_audio(dir / "s.wav");
    const PhoneSequence phones = read_phones(dir / "s.tsv");
    std::vector<std::string> symbols;
    for (const auto& p : phones)
        if (p.symbol != "sil") symbols.push_back(p.symbol);
    EXPECT_EQ(symbols, (std::vector<std::string>{"K", "AH", "M", "HH", "IH", "R", "JH", "AA", "N"}));
    EXPECT_NO_THROW(check_phone_sequence(phones, "s.tsv", 2e-6));
    EXPECT_EQ(phones.front().start_s, 0.0);
    EXPECT_NEAR(phones.back().end_s, audio.duration_s(), 0.020);
    EXPECT_EQ(audio.sample_rate_hz, 22050);
}

TEST(PhonesCli, PipesIntoStream) {
    // `avsi phones … --out - | avsi stream`: the TSV with its header on stdout is what stream reads.
    const fs::path dir = work_dir();
    const std::string cli = quote(AVSI_CLI_PATH);
    const RunResult piped = test::run_command(cli + " phones --text 'Come here John.' --out - | " + cli + " stream");
    ASSERT_EQ(piped.exit_code, 0) << piped.err;
    const std::string& frames = piped.out;
    ASSERT_EQ(frames.rfind("time_s,jaw_rotation,", 0), 0u) << frames.substr(0, 200);
    // One frame per 1/60 s of the utterance: as many as the phones written to a file cover.
    const RunResult r = run_avsi("phones --text 'Come here John.' --out " + quote((dir / "p.tsv").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const double end_s = read_phones(dir / "p.tsv").back().end_s;
    const auto lines = static_cast<std::size_t>(std::count(frames.begin(), frames.end(), '\n'));
    EXPECT_NEAR(static_cast<double>(lines - 1), end_s * 60.0, 2.0);
    // A header in the middle of the stream is still an error with the line number.
    write_text_file(dir / "bad.tsv", "start_s\tend_s\tphone\n0\t0.1\tsil\nstart_s\tend_s\tphone\n");
    const RunResult bad = run_avsi("stream <" + quote((dir / "bad.tsv").string()));
    EXPECT_EQ(bad.exit_code, 1);
    EXPECT_NE(bad.err.find("<stdin>:3:"), std::string::npos) << bad.err;
}

// The Festival path from the command line: the phones of come/here/John,
// contiguous and covering the audio; the same samples and times in two
// processes and in this one.
TEST(PhonesCli, FestivalVoiceGivesTheSameSpeechInEveryProcess) {
    const fs::path dir = work_dir();
    std::vector<Audio> audio;
    std::vector<PhoneSequence> phones;
    for (const char* name : {"a", "b"}) {
        const fs::path wav = dir / (std::string(name) + ".wav"), tsv = dir / (std::string(name) + ".tsv");
        const RunResult r = run_avsi("phones --text 'Come here John.' --tts festival:cmu_us_slt_arctic_hts --wav " +
                                     quote(wav.string()) + " --out " + quote(tsv.string()));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        audio.push_back(read_audio(wav));
        phones.push_back(read_phones(tsv));
    }
    std::vector<std::string> labels;
    const auto& inventory = PhoneInventory::builtin();
    for (const auto& p : phones[0])
        if (p.symbol != "sil") labels.push_back(phone_label(p, inventory.is_vowel(p.symbol)));
    EXPECT_EQ(labels, (std::vector<std::string>{"K", "AH1", "M", "HH", "IH1", "R", "JH", "AA1", "N"}));
    EXPECT_NO_THROW(check_phone_sequence(phones[0], "a.tsv", 2e-6));
    EXPECT_EQ(phones[0].front().start_s, 0.0);
    EXPECT_NEAR(phones[0].back().end_s, audio[0].duration_s(), 1e-6);
    EXPECT_EQ(audio[0].sample_rate_hz, 32000);
    EXPECT_EQ(audio[0].samples, audio[1].samples);
    EXPECT_EQ(phones[0], phones[1]);
    // In this process: the same speech (the WAV holds 16-bit samples).
    TtsSettings s;
    set_tts_voice(s, "festival:cmu_us_slt_arctic_hts");
    const TtsResult here = synthesize_speech("Come here John.", s);
    ASSERT_EQ(here.audio.samples.size(), audio[0].samples.size());
    for (std::size_t i = 0; i < here.audio.samples.size(); ++i)
        ASSERT_NEAR(here.audio.samples[i], audio[0].samples[i], 1.0 / 32768) << i;
    ASSERT_EQ(here.phones.size(), phones[0].size());
    for (std::size_t i = 0; i < here.phones.size(); ++i) {
        EXPECT_EQ(here.phones[i].symbol, phones[0][i].symbol);
        EXPECT_NEAR(here.phones[i].end_s, phones[0][i].end_s, 1e-6);  // TSV keeps 6 decimals
    }
}

TEST(PhonesCli, BadFestivalVoiceListsTheInstalledVoices) {
    const RunResult r = run_avsi("phones --text hi --tts festival:slt --out " + quote((work_dir() / "v.tsv").string()));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("unknown Festival voice \"slt\""), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("installed Festival voices: cmu_us_slt_arctic_hts"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(work_dir() / "v.tsv"));
    const RunResult engine = run_avsi("phones --text hi --tts mary:slt --out " + quote((work_dir() / "v.tsv").string()));
    EXPECT_EQ(engine.exit_code, 1);
    EXPECT_NE(engine.err.find("expected \"espeak:<voice>\" or \"festival:<voice>\""), std::string::npos) << engine.err;
    const RunResult list = run_avsi("phones --list-voices");
    EXPECT_EQ(list.exit_code, 0) << list.err;
    EXPECT_NE(list.out.find("festival:cmu_us_slt_arctic_hts\n"), std::string::npos) << list.out;
    EXPECT_NE(list.out.find("espeak:en-us\n"), std::string::npos) << list.out;
    EXPECT_EQ(run_avsi("phones --text hi --tts festival:kal_diphone --voice en --out x.tsv").exit_code, 2);
}

TEST(PhonesCli, TextGridInReadsBackAsWritten) {
    const fs::path dir = work_dir();
    RunResult r = run_avsi("phones --textgrid " + quote((data_dir / "short.TextGrid").string()) +
                           " --tier phones --out " + quote((dir / "p.TextGrid").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_phones(dir / "p.TextGrid"), read_phones(data_dir / "long.TextGrid"));
    r = run_avsi("phones --lab " + quote((data_dir / "come.lab").string()) + " --out " +
                 quote((dir / "lab.tsv").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_phones(dir / "lab.tsv").size(), 4u);
}

TEST(PhonesCli, MalformedLabelFilesFailWithFileLineAndExitOne) {
    const fs::path dir = work_dir();
    for (const auto& [file, line] : {std::pair{"malformed_number.TextGrid", 17},
                                     {"malformed_truncated.TextGrid", 40},
                                     {"malformed_string.TextGrid", 68}}) {
        SCOPED_TRACE(file);
        const std::string path = (data_dir / file).string();
        const RunResult r = run_avsi("phones --textgrid " + quote(path) + " --out " + quote((dir / "x.tsv").string()));
        EXPECT_EQ(r.exit_code, 1);
        EXPECT_EQ(r.err.rfind(path + ":" + std::to_string(line) + ": error: ", 0), 0u) << r.err;
    }
    const std::string lab = (data_dir / "malformed.lab").string();
    const RunResult r = run_avsi("phones --lab " + quote(lab) + " --out " + quote((dir / "x.tsv").string()));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(r.err.rfind(lab + ":3: error: ", 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.tsv"));
}

TEST(PhonesCli, BadUsageExitsTwoAndBadVoiceOne) {
    EXPECT_EQ(run_avsi("phones --text hi").exit_code, 2);  // --out is required
    EXPECT_EQ(run_avsi("phones --out x.tsv").exit_code, 2);  // no input
    const RunResult voice = run_avsi("phones --text hi --voice en-uss --out " + quote((work_dir() / "v.tsv").string()));
    EXPECT_EQ(voice.exit_code, 1);
    EXPECT_NE(voice.err.find("did you mean \"en-us\""), std::string::npos) << voice.err;
}

TEST(PhonesCli, SwedishAndGermanVoicesGiveOnlyTheirLanguagesPhones) {
    // Sentences written for this test; the output's phones must all be in the
    // language's table (protocols/languages/<lang>/phones.tsv).
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"sv", "Kjolen hängde kvar i garderoben, och sju hungriga björnar sov i den mörka skogen."},
        {"sv", "Fyra fina fåglar flög över den frusna sjön när Ylva åt sin gröt."},
        {"de", "Zwölf Pfarrer möchten heute früh ein Stück Kuchen mit Sahne essen."},
        {"de", "Die Bäckerei öffnet jeden Morgen um sechs Uhr, auch am Sonntag."}};
    for (const auto& [language, text] : cases) {
        SCOPED_TRACE(language + ": " + text);
        const fs::path out = work_dir() / ("lang_" + language + ".tsv");
        const RunResult r = run_avsi("phones --tts espeak:" + language + " --text " + quote(text) + " --out " +
                                     quote(out.string()));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const auto& table = PhoneInventory::builtin().language_phones(language);
        std::size_t speech = 0;
        for (const auto& p : read_phones(out)) {
            EXPECT_NE(std::find(table.begin(), table.end(), p.symbol), table.end()) << p.symbol;
            speech += p.symbol != "sil";
        }
        EXPECT_GT(speech, 30u);
    }
}

TEST(PhonesCli, AVoiceWithoutAPhoneTableExitsOneNamingTheFolder) {
    const RunResult r = run_avsi("phones --tts espeak:fr --text " + quote("Bonjour à tous.") + " --out " +
                                 quote((work_dir() / "fr.tsv").string()));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("protocols/languages/fr/"), std::string::npos) << r.err;
}

TEST(PhonesCli, HelpListsEveryOptionWithDefaults) {
    const RunResult r = run_avsi("phones --help");
    EXPECT_EQ(r.exit_code, 0);
    for (const char* option : {"--text", "--textgrid", "--lab", "--tsv", "--tier", "--tts", "--voice", "--list-voices",
                               "--rate", "--pitch", "--lead-silence", "--trail-silence", "--wav", "--out"})
        EXPECT_NE(r.out.find(option), std::string::npos) << option;
    EXPECT_NE(r.out.find("=espeak:en-us"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("=phones"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace avsi
