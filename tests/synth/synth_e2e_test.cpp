// `avsi synth` and `avsi fap2traj` end to end (the executable at
// AVSI_CLI_PATH): phones from a label file and from text, CSV and MPEG-4 FAP
// output, frame counts by the documented rule (trajectory.h: frames at k/fps
// for k < ceil(duration·fps − 1e-9)), the FAP round trip, exit codes and
// file:line errors for bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/synth/control_model.h"
#include "avsi/synth/fap.h"
#include "avsi/synth/trajectory.h"
#include "support/run_avsi.h"
#include "test_util.h"

namespace avsi::synth {
namespace {

namespace fs = std::filesystem;

const fs::path phones_tsv = fs::path(AVSI_TEST_DATA_DIR) / "core" / "come.tsv";
const fs::path models_dir = fs::path(AVSI_PROTOCOLS_DIR) / "models";

using RunResult = avsi::test::CliResult;

std::string quote(const fs::path& p) { return avsi::test::shell_quote(p.string()); }

// Runs `avsi <args>` with stderr captured; stdout must stay empty.
RunResult run_quiet(const std::string& args) {
    RunResult r = avsi::test::run_avsi(args);
    EXPECT_EQ(r.out, "") << args;
    return r;
}

class SynthCli : public ::testing::Test {
protected:
    void SetUp() override {
        if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
        dir = test::temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    }
    void TearDown() override {
        if (!dir.empty()) fs::remove_all(dir);
    }
    fs::path dir;
};

TEST_F(SynthCli, PhonesToCsvAtThreeFrameRatesMatchesTheLibrary) {
    const PhoneSequence phones = read_phones(phones_tsv);
    const double duration_s = phones.back().end_s;
    const auto model = load_model(models_dir / "cohen-massaro.json");
    for (const double fps : {25.0, 60.0, 90.0}) {
        SCOPED_TRACE(fps);
        const fs::path out = dir / "traj.csv";
        const RunResult r = run_quiet("synth --model " + quote(models_dir / "cohen-massaro.json") +
                                              " --phones " + quote(phones_tsv) + " --fps " +
                                              std::to_string(static_cast<int>(fps)) + " --out " + quote(out));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const Trajectory traj = read_trajectory_csv(out);
        EXPECT_EQ(traj.fps, fps);
        // The documented rule, and by hand for this 0.55 s file.
        ASSERT_EQ(traj.size(), frame_count(duration_s, fps));
        EXPECT_EQ(traj.size(), static_cast<std::size_t>(std::ceil(0.55 * fps - 1e-9)));
        const Trajectory expected = model->synthesize(phones, fps);
        for (std::size_t k = 0; k < traj.size(); ++k)
            for (std::size_t p = 0; p < param_count; ++p)
                ASSERT_NEAR(traj.frames[k][p], expected.frames[k][p], 1e-12) << "frame " << k << " param " << p;
    }
}

TEST_F(SynthCli, PhonesToFapAndBackThroughFap2traj) {
    const PhoneSequence phones = read_phones(phones_tsv);
    const fs::path fap = dir / "come.fap", back = dir / "back.csv";
    RunResult r = run_quiet("synth --model " + quote(models_dir / "ohman.json") + " --phones " +
                                    quote(phones_tsv) + " --fps 25 --out " + quote(fap));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const FapStream stream = read_fap(fap);
    EXPECT_EQ(stream.fps, 25.0);
    EXPECT_EQ(stream.frames.size(), frame_count(phones.back().end_s, 25.0));

    r = run_quiet("fap2traj " + quote(fap) + " --out " + quote(back));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const Trajectory traj = read_trajectory_csv(back);
    EXPECT_EQ(traj.fps, 25.0);
    ASSERT_EQ(traj.size(), stream.frames.size());
    const Trajectory expected = load_model(models_dir / "ohman.json")->synthesize(phones, 25.0);
    const Frame bound = fap_quantisation_bound();
    for (std::size_t k = 0; k < traj.size(); ++k)
        for (std::size_t p = 0; p < param_count; ++p)
            ASSERT_LE(std::abs(traj.frames[k][p] - expected.frames[k][p]), bound[p] + 1e-12)
                << "frame " << k << " param " << p;
}

// `--target greta`: Greta plays every FAP file at 25 fps, so the stream is
// synthesised at 25 fps in Greta's layout (69 mask entries); another --fps is
// refused. fap2traj warns about out-of-range parameters, and --clamp limits them.
TEST_F(SynthCli, GretaTargetAndFap2trajClamp) {
    const PhoneSequence phones = read_phones(phones_tsv);
    const fs::path greta = dir / "greta.fap";
    RunResult r = run_quiet("synth --model " + quote(models_dir / "ohman.json") + " --phones " +
                                    quote(phones_tsv) + " --out " + quote(greta) + " --target greta");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string text = read_text_file(greta);
    EXPECT_EQ(text.rfind("2.1 greta 25 " + std::to_string(frame_count(phones.back().end_s, 25.0)) + "\n", 0), 0u)
        << text.substr(0, 80);
    const std::string mask = text.substr(text.find('\n') + 1, text.find('\n', text.find('\n') + 1) - text.find('\n') - 1);
    EXPECT_EQ(std::count(mask.begin(), mask.end(), ' '), 69) << mask;  // 69 entries, each followed by a space
    const FapStream stream = read_fap(greta);
    EXPECT_EQ(stream.fps, 25.0);
    r = run_quiet("synth --phones " + quote(phones_tsv) + " --out " + quote(dir / "g60.fap") +
                          " --target greta --fps 60");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("Greta plays FAP files at 25 fps, got --fps 60"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "g60.fap"));
    r = run_quiet("synth --phones " + quote(phones_tsv) + " --out " + quote(dir / "g.csv") + " --target greta");
    EXPECT_EQ(r.exit_code, 2);

    // An Xface-style "joy" frame (only the corner FAPs set): the corners
    // stretched and raised past the parameter's range.
    FapStream joy = stream;
    joy.frames.resize(2);
    for (FapFrame& f : joy.frames) f = FapFrame{};
    for (int fap : {6, 7, 12, 13, 53, 54, 59, 60}) {
        for (FapFrame& f : joy.frames) f.mask[static_cast<std::size_t>(fap - 1)] = true;
        joy.frames[1].values[static_cast<std::size_t>(fap - 1)] = fap == 12 || fap == 13 || fap > 58 ? 150.0 : 240.0;
    }
    write_fap(dir / "joy.fap", joy);
    r = run_quiet("fap2traj " + quote(dir / "joy.fap") + " --out " + quote(dir / "joy.csv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("joy.fap: mouth_corner_stretch_left outside its range [-0.5, 1]"), std::string::npos)
        << r.err;
    EXPECT_GT(read_trajectory_csv(dir / "joy.csv").value(1, Param::MouthCornerStretchLeft), 1.0);
    r = run_quiet("fap2traj " + quote(dir / "joy.fap") + " --out " + quote(dir / "joy_clamped.csv") + " --clamp");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("clamped to the range"), std::string::npos) << r.err;
    EXPECT_EQ(read_trajectory_csv(dir / "joy_clamped.csv").value(1, Param::MouthCornerStretchLeft), 1.0);
}

TEST_F(SynthCli, TextToCsvAndFapFollowTheFrameRule) {
    // The phones espeak-ng gives for the text, from `avsi phones`, fix the
    // duration the trajectory must cover.
    RunResult r = run_quiet("phones --text 'Come here John.' --out " + quote(dir / "p.tsv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const double duration_s = read_phones(dir / "p.tsv").back().end_s;
    ASSERT_GT(duration_s, 0.5);

    r = run_quiet("synth --text 'Come here John.' --model " + quote(models_dir / "rule.json") +
                          " --fps 60 --wav " + quote(dir / "s.wav") + " --out " + quote(dir / "t.csv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "s.wav"));
    const Trajectory traj = read_trajectory_csv(dir / "t.csv");
    EXPECT_EQ(traj.fps, 60.0);
    EXPECT_EQ(traj.size(), frame_count(duration_s, 60.0));

    r = run_quiet("synth --text 'Come here John.' --fps 90 --format fap --out " + quote(dir / "t.txt"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const FapStream stream = read_fap(dir / "t.txt");
    EXPECT_EQ(stream.fps, 90.0);
    EXPECT_EQ(stream.frames.size(), frame_count(duration_s, 90.0));
}

// --tts picks the synthesiser as for `avsi phones`: a Festival voice's
// trajectory covers the phones Festival gives, and its audio is the same.
// --voice is an espeak-ng voice, the same as --tts espeak:<voice>.
TEST_F(SynthCli, TextWithAFestivalVoiceFollowsItsPhones) {
    RunResult r = run_quiet("phones --text 'Come here John.' --tts festival:kal_diphone --wav " +
                                    quote(dir / "p.wav") + " --out " + quote(dir / "p.tsv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const double duration_s = read_phones(dir / "p.tsv").back().end_s;
    r = run_quiet("synth --text 'Come here John.' --tts festival:kal_diphone --wav " + quote(dir / "s.wav") +
                          " --out " + quote(dir / "t.csv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_text_file(dir / "s.wav"), read_text_file(dir / "p.wav"));
    EXPECT_EQ(read_trajectory_csv(dir / "t.csv").size(), frame_count(duration_s, 60.0));

    r = run_quiet("synth --text 'Come here John.' --voice en-us --out " + quote(dir / "v.csv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_quiet("synth --text 'Come here John.' --tts espeak:en-us --out " + quote(dir / "w.csv"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_text_file(dir / "v.csv"), read_text_file(dir / "w.csv"));
    EXPECT_EQ(run_quiet("synth --text hi --voice en --tts espeak:en --out x.csv").exit_code, 2);
    // A Festival voice given as --voice says what to give instead.
    r = run_quiet("synth --text hi --voice festival:kal_diphone --out " + quote(dir / "x.csv"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("give \"festival:kal_diphone\" alone (as --tts"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.csv"));
}

TEST_F(SynthCli, BadInputsGiveFileLineAndExitCode1) {
    // A phone line without its label (line 3 of the file).
    const fs::path bad_tsv = fs::path(AVSI_TEST_DATA_DIR) / "core" / "malformed.tsv";
    RunResult r = run_quiet("synth --phones " + quote(bad_tsv) + " --out " + quote(dir / "x.csv"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(r.err.rfind(bad_tsv.string() + ":3", 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.csv"));

    // A FAP file whose first value line has a word for a number (line 3).
    std::string mask = "1 1";
    for (int i = 2; i < 68; ++i) mask += " 0";
    const fs::path bad_fap = dir / "bad.fap";
    test::write_file(bad_fap, "2.1 bad 25 1\n" + mask + "\n0 0 zero\n");
    r = run_quiet("fap2traj " + quote(bad_fap) + " --out " + quote(dir / "y.csv"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(r.err.rfind(bad_fap.string() + ":3", 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(dir / "y.csv"));

    // A model file with a malformed JSON body names its line.
    const fs::path bad_model = dir / "bad.json";
    test::write_file(bad_model, "{\n  \"kind\": \"cohen-massaro\",\n  \"version\": 1,\n  oops\n}\n");
    r = run_quiet("synth --model " + quote(bad_model) + " --phones " + quote(phones_tsv) + " --out " +
                          quote(dir / "z.csv"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(r.err.rfind(bad_model.string() + ":4", 0), 0u) << r.err;

    // A TextGrid whose phone tier is empty names the file (not "<input>").
    const fs::path empty = dir / "empty.TextGrid";
    test::write_file(empty,
                     "File type = \"ooTextFile\"\nObject class = \"TextGrid\"\n\nxmin = 0\nxmax = 1\n"
                     "tiers? <exists>\nsize = 1\nitem []:\n    item [1]:\n        class = \"IntervalTier\"\n"
                     "        name = \"phones\"\n        xmin = 0\n        xmax = 1\n        intervals: size = 0\n");
    r = run_quiet("synth --phones " + quote(empty) + " --out " + quote(dir / "e.csv"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(r.err.rfind(empty.string() + ": error: phones: expected timed phones, got none", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find("<input>"), std::string::npos) << r.err;

    // Bad usage (both --phones and --text) is exit code 2.
    r = run_quiet("synth --phones " + quote(phones_tsv) + " --text hi --out " + quote(dir / "w.csv"));
    EXPECT_EQ(r.exit_code, 2);
}

}  // namespace
}  // namespace avsi::synth
