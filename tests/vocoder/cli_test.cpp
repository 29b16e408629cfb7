// End-to-end runs of `avsi vocode`, `avsi stoi`, `avsi mix` and
// `avsi calibrate` (skipped when the avsi executable has not been built).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "avsi/core/audio.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

namespace fs = std::filesystem;

using test::CliResult;
using test::run_avsi;

class VocoderCli : public ::testing::Test {
protected:
    void SetUp() override {
        if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi not built: " << AVSI_CLI_PATH;
        m_dir = test::temp_dir("vocoder_cli");
        fs::create_directories(m_dir / "in");
        for (int i = 0; i < 3; ++i) {
            Audio a;
            a.sample_rate_hz = 16000;
            const auto x = testing::speech_like(16000, 1.5, 10 + i);
            a.samples.assign(x.begin(), x.end());
            write_audio(m_dir / "in" / ("s" + std::to_string(i) + ".wav"), a);
        }
    }
    void TearDown() override {
        if (!m_dir.empty()) fs::remove_all(m_dir);
    }
    std::string path(const std::string& name) const { return (m_dir / name).string(); }
    fs::path m_dir;
};

TEST_F(VocoderCli, VocodesAFileAndReportsTheSettings) {
    const CliResult r = run_avsi("vocode " + path("in/s0.wav") + " " + path("out.wav") + " --seed 5 --report");
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("Band edges (Hz):      100.0, 531.4, 1720.8, 5000.0"), std::string::npos) << r.output();
    EXPECT_NE(r.output().find("seed 5"), std::string::npos);
    const Audio out = read_audio(path("out.wav"));
    EXPECT_EQ(out.sample_rate_hz, 16000);
    EXPECT_EQ(out.frames(), read_audio(path("in/s0.wav")).frames());
    // Same seed, same file.
    ASSERT_EQ(run_avsi("vocode " + path("in/s0.wav") + " " + path("out2.wav") + " --seed 5").exit_code, 0);
    EXPECT_EQ(read_audio(path("out2.wav")).samples, out.samples);
}

// A loud input (a full-scale square wave: its vocoded copy at the same RMS
// peaks above 1) is scaled down, and `avsi vocode` says so; a quiet one is not.
TEST_F(VocoderCli, WarnsWhenTheOutputWasScaledDownToAvoidClipping) {
    Audio loud;
    loud.sample_rate_hz = 16000;
    for (int n = 0; n < 16000; ++n) loud.samples.push_back((n / 40) % 2 ? 1.0f : -1.0f);
    write_audio(m_dir / "loud.wav", loud);
    const CliResult r = run_avsi("vocode " + path("loud.wav") + " " + path("loud_out.wav"));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("warning: vocoder: the output peaked above full scale; scaled the whole output by -"),
              std::string::npos)
        << r.output();
    const CliResult quiet = run_avsi("vocode " + path("in/s0.wav") + " " + path("quiet_out.wav"));
    ASSERT_EQ(quiet.exit_code, 0) << quiet.output();
    EXPECT_EQ(quiet.output().find("full scale"), std::string::npos) << quiet.output();
}

// Under a memory limit (`ulimit -v`, as a cluster job has), settings that
// hold the whole signal refuse a file that would not fit, before they
// allocate, naming the file and what to do; the default settings stream the
// same file in bounded memory.
TEST_F(VocoderCli, WholeSignalSettingsRefuseAFileThatWouldNotFit) {
    Audio a;
    a.sample_rate_hz = 16000;
    const auto x = testing::speech_like(16000, 300.0, 7);  // 5 minutes: about 1.1 GB for the low-noise carrier
    a.samples.assign(x.begin(), x.end());
    write_audio(m_dir / "long.wav", a);
    const std::string limit = "ulimit -v 700000; ";  // 700 MB of address space
    const CliResult refused = test::run_command(limit + test::shell_quote(AVSI_CLI_PATH) + " vocode --carrier low-noise " +
                                                path("long.wav") + " " + path("long_out.wav"));
    EXPECT_EQ(refused.exit_code, 1) << refused.output();
    EXPECT_NE(refused.output().find("long.wav: error: audio: the low-noise carrier holds the whole signal in memory: "
                                    "about 1.1 GB for these 5.0 minutes"),
              std::string::npos)
        << refused.output();
    EXPECT_FALSE(fs::exists(path("long_out.wav")));
    const CliResult streamed =
        test::run_command(limit + test::shell_quote(AVSI_CLI_PATH) + " vocode " + path("long.wav") + " " + path("long_out.wav"));
    EXPECT_EQ(streamed.exit_code, 0) << streamed.output();
    EXPECT_EQ(read_audio(path("long_out.wav")).frames(), a.frames());
}

// The command line as people type it: a mistyped command or option is named
// with the nearest (`avsi vocod` → vocode, `--band` → --bands), and a value
// outside a set of names fails when the line is read, the same way for every
// such option (tests/e2e/front_end_test.cpp checks every command's); nothing
// is written, exit status 2.
TEST_F(VocoderCli, MistypedCommandOptionsAndNamesSuggestTheNearest) {
    const std::string files = " " + path("in/s0.wav") + " " + path("out.wav");
    const CliResult command = run_avsi("vocod" + files);
    EXPECT_EQ(command.exit_code, 2);
    EXPECT_EQ(command.err, "avsi: 'vocod' is not an avsi command. Did you mean 'vocode'?\n"
                           "Run 'avsi --help' for the commands.\n");
    const CliResult option = run_avsi("vocode --band 3" + files);
    EXPECT_EQ(option.exit_code, 2);
    EXPECT_EQ(option.err, "avsi vocode: unknown option '--band'. Did you mean '--bands'?\n"
                          "Run 'avsi vocode --help' for its options.\n");
    const CliResult stage = run_avsi("vocode --noise speech-shaped --snr-db 0 --noise-stage x" + files);
    EXPECT_EQ(stage.exit_code, 2);
    EXPECT_EQ(stage.err, "avsi vocode: --noise-stage: expected one of before, after, got \"x\"\n"
                         "Run 'avsi vocode --help' for more information.\n");
    // Without --noise too: a value is never silently ignored.
    EXPECT_EQ(run_avsi("vocode --noise-stage aftr" + files).err.find(
                  "avsi vocode: --noise-stage: expected one of before, after, got \"aftr\" (did you mean \"after\"?)"),
              0u);
    const CliResult spacing = run_avsi("vocode --spacing linaer" + files);
    EXPECT_EQ(spacing.exit_code, 2);
    EXPECT_EQ(spacing.err.substr(0, spacing.err.find('\n')),
              "avsi vocode: --spacing: expected one of greenwood, log, linear, got \"linaer\" (did you mean \"linear\"?)");
    EXPECT_FALSE(fs::exists(path("out.wav")));
}

TEST_F(VocoderCli, RefusesAHighCutoffAboveNyquist) {
    const CliResult r = run_avsi("vocode " + path("in/s0.wav") + " " + path("out.wav") + " --high-hz 9000");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output().find("vocoder.high_hz: expected a frequency below the Nyquist frequency (8000.0 Hz)"),
              std::string::npos)
        << r.output();
    EXPECT_FALSE(fs::exists(path("out.wav")));
}

TEST_F(VocoderCli, BatchProcessesEveryFileAndStoiScoresThem) {
    const CliResult r = run_avsi("vocode --batch " + path("in") + " " + path("out") + " --bands 8 --noise speech-shaped --snr-db 5");
    ASSERT_EQ(r.exit_code, 0) << r.output();
    for (int i = 0; i < 3; ++i) EXPECT_TRUE(fs::exists(path("out/s" + std::to_string(i) + ".wav")));
    const CliResult same = run_avsi("stoi " + path("in/s0.wav") + " " + path("in/s0.wav"));
    ASSERT_EQ(same.exit_code, 0);
    EXPECT_EQ(same.output(), "1.000000\n");
    const CliResult d = run_avsi("stoi " + path("in/s0.wav") + " " + path("out/s0.wav") + " --extended");
    ASSERT_EQ(d.exit_code, 0) << d.output();
    const double value = std::stod(d.output());
    EXPECT_GT(value, 0.0);
    EXPECT_LT(value, 1.0);
}

TEST_F(VocoderCli, MixAddsNoiseAndCalibratePrintsItsTable) {
    ASSERT_EQ(run_avsi("mix " + path("in/s0.wav") + " " + path("mixed.wav") + " --noise speech-shaped --snr-db 0").exit_code, 0);
    EXPECT_TRUE(fs::exists(path("mixed.wav")));
    const CliResult c = run_avsi("calibrate --corpus " + path("in") + " --target-estoi 0.4 --max-bands 4 --cutoffs-hz 50,160");
    ASSERT_EQ(c.exit_code, 0) << c.output();
    EXPECT_NE(c.output().find("closest:"), std::string::npos) << c.output();
    EXPECT_NE(c.output().find("50 Hz"), std::string::npos);
}

// A dual-mono stereo copy of a mono file (both channels the same samples).
Audio dual_mono(const Audio& mono) {
    Audio out;
    out.sample_rate_hz = mono.sample_rate_hz;
    out.channels = 2;
    for (float v : mono.samples) {
        out.samples.push_back(v);
        out.samples.push_back(v);
    }
    return out;
}

TEST_F(VocoderCli, StereoIsMixedDownByDefaultAndKeptWithTheSameCarrier) {
    write_audio(path("stereo.wav"), dual_mono(read_audio(path("in/s0.wav"))));
    // Default: one channel out, and a note that says so, naming the file.
    CliResult r = run_avsi("vocode " + path("stereo.wav") + " " + path("mono_out.wav") + " --seed 3");
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_EQ(read_audio(path("mono_out.wav")).channels, 1);
    EXPECT_NE(r.output().find("stereo.wav: 2 channels mixed down to mono"), std::string::npos) << r.output();
    // keep: two channels, the same noise carrier on both, so dual-mono stays dual-mono.
    r = run_avsi("vocode " + path("stereo.wav") + " " + path("kept.wav") + " --seed 3 --channels keep");
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const Audio kept = read_audio(path("kept.wav"));
    ASSERT_EQ(kept.channels, 2);
    EXPECT_EQ(kept.channel(0), kept.channel(1));
    EXPECT_EQ(r.output().find("mixed down"), std::string::npos) << r.output();
    // The kept left channel is what the mono file vocodes to.
    ASSERT_EQ(run_avsi("vocode " + path("in/s0.wav") + " " + path("s0_out.wav") + " --seed 3").exit_code, 0);
    EXPECT_EQ(kept.channel(0), read_audio(path("s0_out.wav")).samples);
    // mix --channels keep adds the same noise to both channels.
    r = run_avsi("mix " + path("stereo.wav") + " " + path("mixed.wav") + " --noise speech-shaped --snr-db 0 --channels keep");
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const Audio mixed = read_audio(path("mixed.wav"));
    ASSERT_EQ(mixed.channels, 2);
    EXPECT_EQ(mixed.channel(0), mixed.channel(1));
    const CliResult both = run_avsi("vocode " + path("stereo.wav") + " " + path("x.wav") + " --channels both");
    EXPECT_EQ(both.exit_code, 2);
    EXPECT_NE(both.err.find("--channels: expected one of mono, keep, got \"both\""), std::string::npos) << both.err;
}

TEST_F(VocoderCli, StoiNamesBothFilesOnARateOrLengthMismatchAndScoresChannels) {
    const Audio clean = read_audio(path("in/s0.wav"));
    Audio shorter = clean;
    shorter.samples.resize(shorter.samples.size() - 100);
    write_audio(path("short.wav"), shorter);
    CliResult r = run_avsi("stoi " + path("in/s0.wav") + " " + path("short.wav"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output().find("short.wav: error: length: expected as many samples as " + path("in/s0.wav")),
              std::string::npos)
        << r.output();
    Audio other_rate = clean;
    other_rate.sample_rate_hz = 22050;
    write_audio(path("rate.wav"), other_rate);
    r = run_avsi("stoi " + path("in/s0.wav") + " " + path("rate.wav"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output().find("rate.wav: error: sample rate: expected the sample rate of " + path("in/s0.wav") +
                            " (16000 Hz), got 22050 Hz"),
              std::string::npos)
        << r.output();
    EXPECT_EQ(r.output().find("<input>"), std::string::npos) << r.output();
    // Stereo: mixed down with a note, or one value per channel.
    write_audio(path("clean2.wav"), dual_mono(clean));
    write_audio(path("deg2.wav"), dual_mono(read_audio(path("in/s1.wav"))));
    r = run_avsi("stoi " + path("clean2.wav") + " " + path("deg2.wav"));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("clean2.wav: 2 channels mixed down to mono for STOI"), std::string::npos) << r.output();
    r = run_avsi("stoi " + path("clean2.wav") + " " + path("deg2.wav") + " --channels keep");
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const auto first = r.output().find('\n');
    ASSERT_NE(first, std::string::npos);
    EXPECT_EQ(r.output().substr(0, first), r.output().substr(first + 1, first)) << r.output();  // two equal lines
    r = run_avsi("stoi " + path("clean2.wav") + " " + path("in/s1.wav") + " --channels keep");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output().find("channels: expected the channel count of"), std::string::npos) << r.output();
}

}  // namespace
}  // namespace avsi::vocoder
