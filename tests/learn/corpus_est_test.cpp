// EST track files (MOCHA-TIMIT / mngu0 style EMA) and the sensor → parameter
// mapping: a test writes a MOCHA-style .ema (binary and ASCII) with moving
// head and a HTK .lab, then reads, maps and evaluates it.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/learn/articulatory_corpus.h"
#include "avsi/learn/est_track.h"
#include "avsi/learn/evaluation.h"
#include "avsi/learn/sensor_mapping.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::synth;
using namespace avsi::learn;

namespace {

constexpr double pi = std::numbers::pi;

using test::temp_dir;

// Known articulation: jaw opening (incisor gap, mm) and lower lip lowering
// relative to the jaw (mm) at time t.
double gap_mm(double t) { return 10.0 * (0.5 - 0.5 * std::cos(2 * pi * 2.0 * t)); }
double lip_drop_mm(double t) { return 2.0 * std::sin(2 * pi * 3.0 * t); }

// A MOCHA-style EMA recording at 500 Hz, coordinates in 1/100 mm, x pointing
// backwards (so the mapping has to find the orientation), the head rotating
// and translating throughout.
EstTrack mocha_recording(double duration_s, bool moving_head) {
    EstTrack t;
    t.channels = {"ui_x", "ui_y", "li_x", "li_y", "ul_x", "ul_y", "ll_x", "ll_y", "tt_x", "tt_y",
                  "tb_x", "tb_y", "td_x", "td_y", "v_x",  "v_y",  "bn_x", "bn_y"};
    const double rate = 500.0;
    for (int k = 0; k < static_cast<int>(duration_s * rate); ++k) {
        const double time = k / rate;
        const double g = gap_mm(time), d = lip_drop_mm(time);
        // Head-frame positions in mm, x forward, y up.
        const double li_x = -0.3 * g, li_y = -g;
        std::vector<std::pair<double, double>> pts = {
            {0, 0},                        // ui
            {li_x, li_y},                  // li
            {8, 3},                        // ul
            {li_x + 8, li_y - 2 - d},      // ll
            {-10, 2},   {-25, 8}, {-40, 10}, {-60, 5},  // tt tb td v
            {10, 40},                      // bn
        };
        const double angle = moving_head ? 0.08 * std::sin(2 * pi * 0.7 * time) : 0.0;
        const double tx = moving_head ? 4.0 * std::sin(2 * pi * 0.4 * time) : 0.0;
        const double ty = moving_head ? 3.0 * std::cos(2 * pi * 0.3 * time) : 0.0;
        std::vector<float> values;
        for (const auto& [x, y] : pts) {
            const double rx = std::cos(angle) * x - std::sin(angle) * y + tx + 100;
            const double ry = std::sin(angle) * x + std::cos(angle) * y + ty - 50;
            values.push_back(static_cast<float>(-rx * 100.0));  // x backwards, 1/100 mm
            values.push_back(static_cast<float>(ry * 100.0));
        }
        t.times_s.push_back(time);
        t.present.push_back(true);
        t.values.push_back(values);
    }
    return t;
}

SensorMappingSettings mocha_settings() {
    SensorMappingSettings s;
    s.mm_per_unit = 0.01;
    return s;
}

}  // namespace

TEST(EstTrack, AsciiAndBinaryRoundTripInBothByteOrders) {
    const fs::path dir = temp_dir("roundtrip");
    EstTrack t = mocha_recording(0.1, true);
    t.present[3] = false;
    for (auto [type, order, name] : {std::tuple{EstDataType::Ascii, EstByteOrder::LittleEndian, "a.ema"},
                                     std::tuple{EstDataType::Binary, EstByteOrder::BigEndian, "be.ema"},
                                     std::tuple{EstDataType::Binary, EstByteOrder::LittleEndian, "le.ema"}}) {
        SCOPED_TRACE(name);
        write_est_track(dir / name, t, type, order);
        const EstTrack r = read_est_track(dir / name);
        EXPECT_EQ(r.channels, t.channels);
        ASSERT_EQ(r.frame_count(), t.frame_count());
        EXPECT_FALSE(r.present[3]);
        EXPECT_TRUE(r.present[4]);
        for (std::size_t k = 0; k < t.frame_count(); k += 7) {
            EXPECT_NEAR(r.times_s[k], t.times_s[k], 1e-6);
            for (std::size_t c = 0; c < t.channels.size(); ++c)
                EXPECT_NEAR(r.values[k][c], t.values[k][c], 1e-3 * std::abs(t.values[k][c]) + 1e-3);
        }
    }
    // The header says what the data holds.
    const std::string head = read_text_file(dir / "be.ema").substr(0, 200);
    EXPECT_NE(head.find("EST_File Track"), std::string::npos);
    EXPECT_NE(head.find("ByteOrder 10"), std::string::npos);
}

TEST(EstTrack, TruncatedBinaryAndBadHeaderAreErrors) {
    const fs::path dir = temp_dir("bad");
    write_est_track(dir / "t.ema", mocha_recording(0.05, false), EstDataType::Binary);
    std::string bytes = read_text_file(dir / "t.ema");
    write_text_file(dir / "short.ema", bytes.substr(0, bytes.size() - 3));
    EXPECT_THROW(read_est_track(dir / "short.ema"), InputError);
    write_text_file(dir / "type.ema", "EST_File Track\nDataType hex\nNumFrames 1\nNumChannels 1\nEST_Header_End\n");
    try {
        read_est_track(dir / "type.ema");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 2);
        EXPECT_EQ(e.first().field, "DataType");
    }
    write_text_file(dir / "ascii.ema",
                    "EST_File Track\nDataType ascii\nNumFrames 2\nNumChannels 1\nBreaksPresent true\n"
                    "EST_Header_End\n0.0 1 5\n0.002 1\n");
    try {
        read_est_track(dir / "ascii.ema");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 8) << e.what();
    }
}

TEST(SensorMapping, RecoversJawAndLipsDespiteHeadMotion) {
    const ParamTrack p = map_sensors_to_params(mocha_recording(2.0, true), mocha_settings(), "mocha");
    EXPECT_DOUBLE_EQ(p.fps, 60.0);
    ASSERT_EQ(p.size(), 120u);
    EXPECT_FALSE(p.has(Param::MouthCornerStretchLeft));
    EXPECT_FALSE(p.has(Param::MouthCornerStretchRight));
    EXPECT_FALSE(p.has(Param::JawShift));
    double max_jaw = 0, max_thrust = 0, max_lld = 0, max_raise = 0;
    for (std::size_t k = 0; k < p.size(); ++k) {
        const double t = p.time_s(k);
        max_jaw = std::max(max_jaw, std::abs(p.frames[k][index(Param::JawRotation)] - gap_mm(t) / 20.0));
        max_thrust = std::max(max_thrust, std::abs(p.frames[k][index(Param::JawThrust)]));
        max_lld = std::max(max_lld, std::abs(p.frames[k][index(Param::LowerLipDepression)] - lip_drop_mm(t) / 10.0));
        max_raise = std::max(max_raise, std::abs(p.frames[k][index(Param::UpperLipRaise)]));
    }
    // 5th-percentile rest of a raised cosine is 0.06 mm; float32 storage adds ~1e-3 mm.
    EXPECT_LT(max_jaw, 0.01);
    EXPECT_LT(max_thrust, 0.01);  // the incisor's backward path is all rotation
    EXPECT_LT(max_lld, 0.01);
    EXPECT_LT(max_raise, 0.01);   // the upper lip does not move in the head frame

    // Without head-motion removal the same data maps badly.
    SensorMappingSettings no_ref = mocha_settings();
    no_ref.reference_sensors.clear();
    const ParamTrack q = map_sensors_to_params(mocha_recording(2.0, true), no_ref, "mocha");
    double worst = 0;
    for (std::size_t k = 0; k < q.size(); ++k)
        worst = std::max(worst, std::abs(q.frames[k][index(Param::UpperLipRaise)]));
    EXPECT_GT(worst, 0.05);
}

TEST(SensorMapping, MissingChannelNamesThePresentOnes) {
    EstTrack t = mocha_recording(0.1, false);
    t.channels[6] = "lo_x";
    try {
        map_sensors_to_params(t, mocha_settings(), "x.ema");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        const std::string text = e.what();
        EXPECT_NE(text.find("ll_x"), std::string::npos) << text;
        EXPECT_NE(text.find("did you mean"), std::string::npos) << text;
        EXPECT_NE(text.find("channels present: ui_x"), std::string::npos) << text;
    }
}

TEST(SensorCorpus, MochaStyleEmaAndLabReadMappedAndEvaluated) {
    const fs::path dir = temp_dir("corpus");
    write_est_track(dir / "fsew0_001.ema", mocha_recording(1.0, true), EstDataType::Binary, EstByteOrder::BigEndian);
    write_est_track(dir / "fsew0_002.ema", mocha_recording(1.0, true), EstDataType::Ascii);
    // HTK label file, 100 ns units.
    const std::string lab = "0 2000000 sil\n2000000 4500000 AA1\n4500000 5500000 P\n5500000 8000000 IY0\n"
                            "8000000 10000000 sil\n";
    write_text_file(dir / "fsew0_001.lab", lab);
    write_text_file(dir / "fsew0_002.lab", lab);
    write_text_file(dir / "corpus.json",
                    R"({"format": "avsi-articulatory-corpus", "version": 1, "name": "mocha-style",
                        "sensor_mapping": {"mm_per_unit": 0.01, "reference_sensors": ["bn", "ui"]},
                        "utterances": [
                          {"id": "fsew0_001", "track": "fsew0_001.ema", "labels": "fsew0_001.lab", "split": "test"},
                          {"id": "fsew0_002", "track": "fsew0_002.ema", "labels": "fsew0_002.lab", "split": "test"}]})");
    const ArticulatoryCorpus corpus = load_articulatory_corpus(dir);
    EXPECT_EQ(corpus.entries[0].kind, TrackKind::Sensors);
    const CorpusSplit split = split_corpus(corpus);
    ASSERT_EQ(split.test_ids.size(), 2u);
    const auto utterances = load_corpus_utterances(corpus, split.test_ids);
    ASSERT_EQ(utterances.size(), 2u);
    EXPECT_EQ(utterances[0].phones.size(), 5u);

    // The true articulation scores almost perfectly; a still face does not.
    const PredictFunction truth = [](const PhoneSequence&, std::span<const double> times, std::vector<Frame>& out) {
        out.assign(times.size(), Frame{});
        for (std::size_t k = 0; k < times.size(); ++k) {
            out[k][index(Param::JawRotation)] = gap_mm(times[k]) / 20.0;
            out[k][index(Param::LowerLipDepression)] = lip_drop_mm(times[k]) / 10.0;
        }
    };
    const PredictFunction still = [](const PhoneSequence&, std::span<const double> times, std::vector<Frame>& out) {
        out.assign(times.size(), Frame{});
    };
    const auto scores = evaluate_predictors(utterances, {{"truth", truth}, {"still", still}});
    const auto all = static_cast<std::size_t>(FrameSubset::AllNonSilence);
    const Score jaw = scores[0].per_param[all][index(Param::JawRotation)];
    EXPECT_NEAR(static_cast<double>(jaw.frames), 2.0 * 36.0, 2.0);  // 0.2 s … 0.8 s at 60 fps, twice
    EXPECT_LT(jaw.rmse_percent, 1.0);
    EXPECT_GT(jaw.pearson, 0.999);
    EXPECT_GT(scores[0].per_param[all][index(Param::LowerLipDepression)].pearson, 0.999);
    EXPECT_EQ(scores[0].per_param[all][index(Param::JawShift)].frames, 0u);  // missing: left out
    EXPECT_GT(scores[1].per_param[all][index(Param::JawRotation)].rmse_percent, 10.0);
}
