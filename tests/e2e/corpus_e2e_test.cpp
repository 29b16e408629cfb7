// Sentence corpora end to end (issue 10): a user-supplied corpus of WAV
// recordings with TextGrid phone labels builds stimuli through an unchanged
// `avsi build-stimuli` (the manifest shows the given audio, not TTS);
// `avsi corpus import` and `avsi corpus balance` write corpora the loader
// reads; `avsi design` accepts the shipped protocol for the study's 25 subjects.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "avsi/core/audio.h"
#include "avsi/core/corpus.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/tts.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

using RunResult = test::CliResult;
using test::run_avsi;

fs::path work_dir(const std::string& name) { return test::temp_dir("e2e_corpus_" + name); }

std::string quote(const std::string& s) { return test::shell_quote(s); }

TEST(UserCorpus, WavAndTextGridRecordingsReplaceTtsWithNoCodeChange) {
    const fs::path dir = work_dir("user");
    // The "recordings": speech slower and higher than the protocol's TTS
    // would make, so their durations cannot be confused with TTS output.
    const std::map<std::string, std::string> texts{{"u1", "The boy fell from the window."},
                                                   {"u2", "She cut the bread with a knife."}};
    TtsSettings recorded;
    recorded.rate_wpm = 100;
    recorded.pitch = 80;
    std::map<std::string, Audio> audio;
    std::map<std::string, double> tts_duration_s;
    fs::create_directories(dir / "recordings");
    for (const auto& [id, text] : texts) {
        const TtsResult r = synthesize_speech(text, recorded);
        write_audio(dir / "recordings" / (id + ".wav"), r.audio);
        write_phones_textgrid(dir / "recordings" / (id + ".TextGrid"), r.phones);
        audio[id] = read_audio(dir / "recordings" / (id + ".wav"));
        tts_duration_s[id] = synthesize_speech(text).audio.duration_s();
        ASSERT_GT(audio[id].duration_s() - tts_duration_s[id], 0.3) << id;
    }
    write_text_file(dir / "corpus.csv",
                    "id,text,keywords,list,audio,labels\n"
                    "u1,The boy fell from the window.,boy|boys;fell;window|windows,1,recordings/u1.wav,"
                    "recordings/u1.TextGrid\n"
                    "u2,She cut the bread with a knife.,cut;bread;knife|knives,2,recordings/u2.wav,"
                    "recordings/u2.TextGrid\n");
    const fs::path model = fs::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json";
    write_text_file(dir / "protocol.toml", "[experiment]\nname = \"user-corpus\"\nseed = 3\n\n"
                                           "[corpus]\nsentences = \"corpus.csv\"\naudio = \"recordings\"\n\n"
                                           "[[condition]]\nname = \"clean\"\nface = \"still\"\naudio = \"clean\"\n\n"
                                           "[[condition]]\nname = \"rule\"\nmodel = \"" +
                                               model.string() +
                                               "\"\n\n"
                                               "[vocoder]\nbands = 3\nlow_hz = 100\nhigh_hz = 5000\n\n"
                                               "[design]\nlists = 2\nsentences_per_list = 1\n\n"
                                               "[render]\nfps = 30\nwidth = 64\nheight = 48\n");

    const RunResult r = run_avsi("build-stimuli " + quote((dir / "protocol.toml").string()) + " --out " +
                                     quote((dir / "stimuli").string()) + " --jobs 1");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto manifest = nlohmann::json::parse(read_text_file(dir / "stimuli" / "manifest.json"));
    ASSERT_EQ(manifest["stimuli"].size(), 4u);
    for (const auto& e : manifest["stimuli"]) {
        const std::string id = e["sentence"], condition = e["condition"];
        SCOPED_TRACE(id + "/" + condition);
        const double duration_s = e["audio_duration_s"];
        EXPECT_NEAR(duration_s, audio[id].duration_s(), 1e-6);
        EXPECT_GT(duration_s - tts_duration_s[id], 0.3);
        // The video runs as long as the recording (to within a frame).
        EXPECT_NEAR(double(e["duration_s"]), audio[id].duration_s(), 1.0 / 30.0 + 1e-9);
        const fs::path wav = dir / "stimuli" / std::string(e["wav"]);
        EXPECT_EQ(sha256_file(wav), std::string(e["wav_sha256"]));
        const Audio out = read_audio(wav);
        ASSERT_EQ(out.samples.size(), audio[id].samples.size());
        if (condition == "clean") {
            // Unprocessed but for the protocol's speech level: the given
            // recording times the manifest's gain, sample for sample (16-bit
            // WAV both ways).
            const double gain = std::pow(10.0, double(e["level"]["gain_db"]) / 20.0);
            EXPECT_GT(std::fabs(double(e["level"]["gain_db"])), 0.01);  // a gain was applied
            double max_diff = 0.0;
            for (std::size_t i = 0; i < out.samples.size(); ++i)
                max_diff = std::max(max_diff, std::fabs(double(out.samples[i]) - gain * audio[id].samples[i]));
            EXPECT_LT(max_diff, 1e-4);
        }
    }
}

TEST(CorpusImport, ProposesKeywordsAndWritesACorpusTheLoaderReads) {
    const fs::path dir = work_dir("import");
    write_text_file(dir / "sentences.txt",
                    "# a user's unmarked list\nThe old man walked with a stick.\n\nIt is in the box.\n");
    const RunResult r = run_avsi("corpus import " + quote((dir / "sentences.txt").string()) + " --out " +
                                     quote((dir / "corpus.csv").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const Corpus c = read_corpus(dir / "corpus.csv");
    ASSERT_EQ(c.sentences.size(), 2u);
    ASSERT_EQ(c.sentences[0].keywords.size(), 3u);
    EXPECT_EQ(c.sentences[1].keywords.size(), 1u);
    EXPECT_NE(r.out.find("s001 \"The old man walked with a stick.\""), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("only 1 of 3: check by hand"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("syllables: 5  <- outside 7–9"), std::string::npos) << r.out;

    const RunResult missing = run_avsi("corpus import " + quote((dir / "nope.txt").string()) + " --out x.csv");
    EXPECT_EQ(missing.exit_code, 2) << missing.err;
}

TEST(CorpusBalance, AssignsBalancedListsAndWritesTheReport) {
    const fs::path dir = work_dir("balance");
    write_text_file(dir / "in.csv",
                    "id,text,keywords,list\n"
                    "a,The boy fell from the window.,boy;fell;window,\n"
                    "b,She cut the bread with a knife.,cut;bread;knife,\n"
                    "c,The children played in the park.,children;played;park,\n"
                    "d,He washed his car on Sunday.,washed;car;Sunday,\n"
                    "e,The train was late this morning.,train;late;morning,\n"
                    "f,The old man walked with a stick.,old;walked;stick,\n"
                    "g,She found her keys in the drawer.,found;keys;drawer,\n"
                    "w,The sun was shining all day.,sun;shining;day,warmup\n");
    const std::string args = "corpus balance " + quote((dir / "in.csv").string()) + " --out " +
                             quote((dir / "out.csv").string()) + " --report " + quote((dir / "balance.md").string()) +
                             " --lists 2 --per-list 3 --restarts 2 --iterations 500 --seed 9";
    const RunResult r = run_avsi(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const Corpus c = read_corpus(dir / "out.csv");
    std::map<std::string, int> count;
    for (const auto& s : c.sentences) ++count[s.list];
    EXPECT_EQ(count["1"], 3);
    EXPECT_EQ(count["2"], 3);
    EXPECT_EQ(count["warmup"], 1);
    EXPECT_EQ(count[""], 1);
    const std::string report = read_text_file(dir / "balance.md");
    EXPECT_NE(report.find("F(1, 16)"), std::string::npos) << report;  // 2 lists × 9 keywords
    EXPECT_NE(report.find("--seed 9"), std::string::npos) << report;
    // Deterministic: the same command gives the same lists.
    const std::string first = read_text_file(dir / "out.csv");
    ASSERT_EQ(run_avsi(args).exit_code, 0);
    EXPECT_EQ(read_text_file(dir / "out.csv"), first);
}

// Runs `avsi corpus balance` on a shipped corpus folder into `dir`, expects
// the committed lists and, but for the paths in its first lines, the
// committed report; returns the new report.
std::string rebalance_shipped(const fs::path& corpus, const fs::path& dir, const std::string& extra) {
    const RunResult r = run_avsi("corpus balance " + quote((corpus / "sentences.csv").string()) + " --out " +
                                 quote((dir / "sentences.csv").string()) + " --report " +
                                 quote((dir / "balance.md").string()) + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const Corpus shipped = read_corpus(corpus / "sentences.csv");
    const Corpus again = read_corpus(dir / "sentences.csv");
    EXPECT_EQ(again.sentences.size(), shipped.sentences.size());
    for (std::size_t i = 0; i < std::min(shipped.sentences.size(), again.sentences.size()); ++i)
        EXPECT_EQ(again.sentences[i].list, shipped.sentences[i].list) << shipped.sentences[i].id;
    const std::string report = read_text_file(dir / "balance.md");
    auto body = [](const std::string& text) { return text.substr(text.find("## Per list")); };
    EXPECT_EQ(body(report), body(read_text_file(corpus / "balance.md")));
    return report;
}

TEST(ShippedCorpus, BalanceCommandReproducesTheCommittedListsAndReport) {
    // The command in protocols/corpus/README.md, written elsewhere.
    rebalance_shipped(fs::path(AVSI_PROTOCOLS_DIR) / "corpus", work_dir("shipped"), "");
}

TEST(ShippedCorpus, SwedishBalanceReproducesTheCommittedListsWithoutFrequency) {
    // The command in protocols/languages/sv/sentences/README.md: espeak-ng's
    // Swedish voice, no keyword frequency (English's counts).
    const std::string report = rebalance_shipped(fs::path(AVSI_PROTOCOLS_DIR) / "languages" / "sv" / "sentences",
                                                 work_dir("shipped_sv"), " --voice sv");
    EXPECT_EQ(report.find("log10"), std::string::npos) << report;
    EXPECT_NE(report.find("No keyword frequency"), std::string::npos) << report;
}

TEST(ShippedProtocol, DesignsListsForTheStudysTwentyFiveSubjects) {
    const fs::path dir = work_dir("design");
    const RunResult r = run_avsi("design " + quote(std::string(AVSI_PROTOCOLS_DIR) + "/beskow2004-en.toml") +
                                     " --subjects 25 --out " + quote((dir / "lists.csv").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string lists = read_text_file(dir / "lists.csv");
    // 25 subjects × (15 warm-up + 6 practice + 90 test) trials, one line each plus the header.
    EXPECT_EQ(std::count(lists.begin(), lists.end(), '\n'), 25 * (15 + 6 + 90) + 1);
}

}  // namespace
}  // namespace avsi
