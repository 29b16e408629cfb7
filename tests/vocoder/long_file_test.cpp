// Whole avsi processes on an hour of audio (issue 21): `avsi vocode`, `avsi
// mix` (with a noise recording) and `avsi stoi` stream their files, so
// their peak resident memory, read from the finished process (wait4's
// ru_maxrss), stays under 128 MiB whatever the length; `avsi vocode --batch`
// with a noise recording under 128 MiB per worker. A test of memory,
// not of time (label slow: about a minute on the 2-core machine).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "avsi/core/audio_stream.h"
#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"
#include "test_signals.h"

namespace avsi::vocoder {
namespace {

namespace fs = std::filesystem;

struct ProcessRun {
    int exit_code = -1;
    long peak_rss_kib = 0;
    std::string output;
};

// Runs avsi with `args`, stdout and stderr into `log`; the exit code and
// the process's peak resident set size.
ProcessRun run_measured(const std::vector<std::string>& args, const fs::path& log) {
    const test::Finished f = test::wait_avsi(test::start_avsi(args, log));
    return {f.exit_code, f.peak_rss_kib, read_text_file(log)};
}

// `seconds` of speech-like sound at `rate`: a 10 s piece repeated, written
// block by block.
void write_long(const fs::path& path, int rate, double seconds, std::uint64_t seed) {
    const std::vector<double> piece = testing::speech_like(rate, 10.0, seed);
    std::vector<float> block(piece.begin(), piece.end());
    AudioFileWriter out(path, rate, 1);
    const auto total = static_cast<std::size_t>(std::llround(seconds * rate));
    for (std::size_t written = 0; written < total;) {
        const std::size_t n = std::min(block.size(), total - written);
        out.write(block.data(), n);
        written += n;
    }
    out.commit();
}

constexpr long kBoundKib = 128 * 1024;

TEST(LongFile, VocodeMixAndStoiOfAnHourStayUnder128MiB) {
    if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi not built: " << AVSI_CLI_PATH;
    const fs::path dir = test::temp_dir("long_file");
    // The files (about 0.5 GB) go whether the test passes or stops early.
    struct Cleanup {
        fs::path dir;
        ~Cleanup() {
            std::error_code ignored;
            fs::remove_all(dir, ignored);
        }
    } cleanup{dir};
    const fs::path speech = dir / "hour.wav", noise = dir / "noise.wav";
    write_long(speech, 22050, 3600.0, 5);
    write_long(noise, 22050, 95.0, 6);
    const std::size_t frames = AudioFileReader(speech).frames();
    ASSERT_EQ(frames, 3600u * 22050u);

    const ProcessRun vocoded = run_measured({"vocode", speech.string(), (dir / "vocoded.wav").string()}, dir / "vocode.log");
    EXPECT_EQ(vocoded.exit_code, 0) << vocoded.output;
    EXPECT_LE(vocoded.peak_rss_kib, kBoundKib) << "avsi vocode of 1 hour";
    EXPECT_EQ(AudioFileReader(dir / "vocoded.wav").frames(), frames);

    const ProcessRun mixed = run_measured({"mix", speech.string(), (dir / "mixed.wav").string(), "--noise", noise.string(),
                                "--snr-db", "0", "--snr-reference", "active"},
                               dir / "mix.log");
    EXPECT_EQ(mixed.exit_code, 0) << mixed.output;
    EXPECT_LE(mixed.peak_rss_kib, kBoundKib) << "avsi mix of 1 hour";
    EXPECT_EQ(AudioFileReader(dir / "mixed.wav").frames(), frames);

    const ProcessRun scored = run_measured({"stoi", speech.string(), (dir / "vocoded.wav").string()}, dir / "stoi.log");
    EXPECT_EQ(scored.exit_code, 0) << scored.output;
    EXPECT_LE(scored.peak_rss_kib, kBoundKib) << "avsi stoi of 1 hour";
    const double d = std::atof(scored.output.c_str());
    EXPECT_GT(d, 0.2) << scored.output;
    EXPECT_LT(d, 1.0) << scored.output;

    // vocode --batch with a noise recording added before vocoding: two
    // hour-long files (hard links of one) on two workers, 128 MiB per worker.
    const fs::path batch_in = dir / "batch_in", batch_out = dir / "batch_out";
    fs::create_directories(batch_in);
    fs::create_hard_link(speech, batch_in / "a.wav");
    fs::create_hard_link(speech, batch_in / "b.wav");
    const ProcessRun batch = run_measured({"vocode", "--batch", batch_in.string(), batch_out.string(), "--noise",
                                       noise.string(), "--snr-db", "5", "--threads", "2"},
                                      dir / "batch.log");
    EXPECT_EQ(batch.exit_code, 0) << batch.output;
    EXPECT_LE(batch.peak_rss_kib, 2 * kBoundKib) << "avsi vocode --batch --threads 2 of two 1-hour files";
    EXPECT_EQ(AudioFileReader(batch_out / "a.wav").frames(), frames);
    EXPECT_EQ(AudioFileReader(batch_out / "b.wav").frames(), frames);
    std::printf("peak RSS of 1 hour at 22.05 kHz: vocode %.1f MiB, mix %.1f MiB, stoi %.1f MiB; "
                "vocode --batch with noise, 2 files on 2 workers %.1f MiB\n",
                vocoded.peak_rss_kib / 1024.0, mixed.peak_rss_kib / 1024.0, scored.peak_rss_kib / 1024.0,
                batch.peak_rss_kib / 1024.0);
}

}  // namespace
}  // namespace avsi::vocoder
