// ANN input encoding, window alignment, streaming and causality (Beskow §4.4–4.5).
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "ann_test_util.h"
#include "support/run_avsi.h"
#include "avsi/core/error.h"
#include "avsi/synth/ann.h"

namespace avsi::synth {
namespace {

using test::make_phones;

FeatureVector features(const std::string& symbol, bool stressed = false) {
    return PhoneInventory::builtin().features_of(Phone{symbol, 0, 1, stressed});
}

TEST(AnnEncoding, FramesTakeThePhoneTheirTimeFallsInAndSilenceOutside) {
    // 60 fps: frame k at k/60 s. P covers [0.05, 0.1) → frames 3, 4, 5; gap
    // [0.1, 0.15) silence → frames 6…8; AA1 [0.15, 0.2) → frames 9…11.
    PhoneSequence phones{{"P", 0.05, 0.1, false}, {"AA", 0.15, 0.2, true}};
    const auto f = encode_frame_features(phones, 60.0, 15);
    ASSERT_EQ(f.size(), 15u);
    for (std::size_t k : {0u, 1u, 2u, 6u, 7u, 8u, 12u, 13u, 14u}) EXPECT_EQ(f[k], features("sil")) << k;
    for (std::size_t k : {3u, 4u, 5u}) EXPECT_EQ(f[k], features("P")) << k;
    for (std::size_t k : {9u, 10u, 11u}) EXPECT_EQ(f[k], features("AA", true)) << k;
    EXPECT_EQ(f[9][static_cast<std::size_t>(Feature::Stress)], 1.0f);
    EXPECT_NE(features("P"), features("sil"));
}

TEST(AnnEncoding, WindowHoldsFramesKMinusBToKPlusAOldestFirst) {
    const AnnConfig config{60.0, 2, 3, 5};
    std::vector<FeatureVector> f(10);
    for (std::size_t k = 0; k < f.size(); ++k) f[k].fill(static_cast<float>(k + 1));
    std::vector<float> x(config.inputs());
    ASSERT_EQ(x.size(), 6u * feature_count);
    window_input(f, 5, config, x);
    for (std::size_t j = 0; j < 6; ++j)
        for (std::size_t i = 0; i < feature_count; ++i) EXPECT_EQ(x[j * feature_count + i], static_cast<float>(5 - 3 + j + 1));
    // At the edges, frames outside the utterance are silence.
    window_input(f, 0, config, x);
    for (std::size_t j = 0; j < 3; ++j)
        for (std::size_t i = 0; i < feature_count; ++i) EXPECT_EQ(x[j * feature_count + i], features("sil")[i]);
    EXPECT_EQ(x[3 * feature_count], 1.0f);
    window_input(f, 8, config, x);
    EXPECT_EQ(x[4 * feature_count], 10.0f);
    for (std::size_t i = 0; i < feature_count; ++i) EXPECT_EQ(x[5 * feature_count + i], features("sil")[i]);
}

// A one-unit network whose output is tanh of the Vowel feature at window slot
// `slot`: the output at frame k shows which input frame the slot reads.
AnnModel probe_model(const AnnConfig& config, std::size_t slot) {
    AnnNetwork n;
    n.group = AnnGroup{"occlusion", {Param::JawRotation}, 1};
    n.W.assign(config.inputs(), 0.0f);
    n.W[slot * feature_count + static_cast<std::size_t>(Feature::Vowel)] = 1.0f;
    n.U.assign(static_cast<std::size_t>(config.delays), 0.0f);
    n.b = {0.0f};
    n.V = {1.0f};
    n.c = {0.0f};
    return AnnModel(config, {n});
}

TEST(AnnEncoding, LookAheadSlotSeesTheFrameAFramesLater) {
    const AnnConfig config{60.0, 2, 28, 5};
    // The vowel starts at frame 10 (t = 10/60).
    const PhoneSequence phones{{"P", 0.0, 10.0 / 60.0, false}, {"AA", 10.0 / 60.0, 1.0, true}};
    const auto range = param_info(Param::JawRotation).range();
    const AnnModel newest = probe_model(config, config.window() - 1);   // reads frame k + 2
    const AnnModel current = probe_model(config, 28);                    // reads frame k
    const auto a = newest.run_frames(phones, 20);
    const auto b = current.run_frames(phones, 20);
    const double on = std::tanh(1.0) * range;
    for (std::size_t k = 0; k < 20; ++k) {
        EXPECT_NEAR(a[k][0], k + 2 >= 10 ? on : 0.0, 1e-6) << k;
        EXPECT_NEAR(b[k][0], k >= 10 ? on : 0.0, 1e-6) << k;
        EXPECT_EQ(a[k][index(Param::LipRounding)], 0.0);   // no network: neutral
    }
}

TEST(AnnEncoding, RecurrentDelaysUseHiddenStateOfDFramesBefore) {
    // One unit, U_3 = 1 only: h_t = tanh(x_t + h_{t−3}); with x = 1 at frame 0 only.
    AnnConfig config{60.0, 0, 0, 5};
    AnnNetwork n;
    n.group = AnnGroup{"occlusion", {Param::JawRotation}, 1};
    n.W.assign(config.inputs(), 0.0f);
    n.W[static_cast<std::size_t>(Feature::Vowel)] = 1.0f;
    n.U = {0.0f, 0.0f, 1.0f, 0.0f, 0.0f};
    n.b = {0.0f};
    n.V = {1.0f};
    n.c = {0.0f};
    const AnnModel m(config, {n});
    const PhoneSequence phones{{"AA", 0.0, 1.0 / 60.0, true}, {"P", 1.0 / 60.0, 0.2, false}};
    const auto out = m.run_frames(phones, 10);
    const double range = param_info(Param::JawRotation).range();
    double h0 = std::tanh(1.0f);
    EXPECT_NEAR(out[0][0], h0 * range, 1e-6);
    EXPECT_NEAR(out[1][0], 0.0, 1e-6);
    EXPECT_NEAR(out[3][0], std::tanh(static_cast<float>(h0)) * range, 1e-6);
    EXPECT_NEAR(out[4][0], 0.0, 1e-6);
}

TEST(AnnStreaming, StreamedFramesEqualBatchFrames) {
    const AnnConfig config = ann2_config();
    const AnnModel model = test::random_ann(config, 8, 7);
    const PhoneSequence phones = test::random_phones(3, 12);
    const auto batch = model.run_frames(phones, frame_count(phones.back().end_s, config.fps));
    AnnStreamer s(model);
    std::vector<StreamFrame> got;
    for (const auto& p : phones) {
        s.push(p);
        for (auto& f : s.take_ready()) got.push_back(f);
    }
    s.finish();
    for (auto& f : s.take_ready()) got.push_back(f);
    ASSERT_EQ(got.size(), batch.size());
    for (std::size_t k = 0; k < got.size(); ++k) {
        EXPECT_EQ(got[k].index, k);
        EXPECT_EQ(got[k].values, batch[k]) << k;
    }
}

TEST(AnnStreaming, EachFrameIsEmittedAsSoonAsItsLookAheadIsKnown) {
    // A recogniser reporting one frame-long piece at a time: after the piece
    // ending at (j+1)/fps, frames 0 … j − A are out, and no more.
    const AnnConfig config = ann2_config();
    const AnnModel model = test::random_ann(config, 4, 1);
    AnnStreamer s(model);
    std::size_t emitted = 0;
    for (int j = 0; j < 40; ++j) {
        const std::string symbol = (j / 6) % 2 ? "AA" : "M";
        s.push(Phone{symbol, j / 60.0, (j + 1) / 60.0, true});
        emitted += s.take_ready().size();
        const int expected = std::max(0, j + 1 - config.look_ahead);
        EXPECT_EQ(emitted, static_cast<std::size_t>(expected)) << j;
    }
    s.finish();
    emitted += s.take_ready().size();
    EXPECT_EQ(emitted, 40u);
}

TEST(AnnStreaming, PhonesAfterTPlusLookAheadDoNotChangeOutputUpToT) {
    const AnnConfig config = ann2_config();
    const AnnModel model = test::random_ann(config, 8, 11);
    const PhoneSequence base = test::random_phones(5, 14);
    const double t = 0.6;   // output up to t must not depend on phones after t + A/fps
    const double cut = t + config.look_ahead / config.fps;
    auto stream_all = [&](const PhoneSequence& phones) {
        AnnStreamer s(model);
        std::vector<StreamFrame> out;
        for (const auto& p : phones) s.push(p);
        s.finish();
        return s.take_ready();
    };
    // Change every phone (or part of a phone) after `cut`: split at cut and
    // replace the rest with other phones of other durations.
    PhoneSequence changed;
    for (const auto& p : base) {
        if (p.end_s <= cut) {
            changed.push_back(p);
        } else {
            if (p.start_s < cut) changed.push_back(Phone{p.symbol, p.start_s, cut + 1e-9, p.stressed});
            break;
        }
    }
    double s0 = changed.back().end_s;
    for (const char* sym : {"UW", "F", "IY", "B", "sil"}) {
        changed.push_back(Phone{sym, s0, s0 + 0.13, true});
        s0 += 0.13;
    }
    const auto a = stream_all(base);
    const auto b = stream_all(changed);
    const auto last = static_cast<std::size_t>(std::floor(t * config.fps));
    ASSERT_GT(a.size(), last + 5);
    ASSERT_GT(b.size(), last + 5);
    for (std::size_t k = 0; k <= last; ++k) EXPECT_EQ(a[k].values, b[k].values) << k;
    // …and the change is visible soon after (the test would not notice otherwise).
    bool differs = false;
    for (std::size_t k = last + 1; k < std::min(a.size(), b.size()); ++k) differs |= a[k].values != b[k].values;
    EXPECT_TRUE(differs);
}

TEST(AnnStreaming, RejectsPhonesGoingBackInTime) {
    const AnnModel model = test::random_ann(ann2_config(), 4, 1);
    AnnStreamer s(model);
    s.push(Phone{"AA", 0.0, 0.2, true});
    EXPECT_THROW(s.push(Phone{"P", 0.1, 0.3, false}), InputError);
    EXPECT_THROW(s.push(Phone{"P", 0.3, 0.25, false}), InputError);
}

TEST(AnnModelFile, EvaluateAtFrameTimesMatchesRunFramesAndInterpolatesBetween) {
    const AnnModel model = test::random_ann(ann1_config(), 6, 2);
    const PhoneSequence phones = make_phones({{"sil", 0.1}, {"M", 0.08}, {"AA", 0.15}, {"sil", 0.1}});
    const Trajectory t = model.synthesize(phones, 60.0);
    const auto f = model.run_frames(phones, t.size());
    for (std::size_t k = 0; k < t.size(); ++k) EXPECT_EQ(t.frames[k], f[k]);
    std::vector<Frame> mid;
    const double time = 10.5 / 60.0;
    model.evaluate(phones, std::span<const double>(&time, 1), mid);
    EXPECT_NEAR(mid[0][0], 0.5 * (f[10][0] + f[11][0]), 1e-12);
}

}  // namespace
}  // namespace avsi::synth

namespace avsi::synth {
namespace {

// `avsi stream`: frames on stdout equal the batch frames of the same phones.
TEST(AnnStreamCli, StdinPhonesGiveTheBatchFrames) {
    if (!std::filesystem::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
    const auto dir = test::temp_dir("ann_stream_cli");
    const AnnModel model = test::random_ann(ann2_config(), 5, 21);
    save_model(model, dir / "m.json");
    const PhoneSequence phones = make_phones({{"sil", 0.1}, {"M", 0.07}, {"AA", 0.2}, {"P", 0.08}, {"sil", 0.1}});
    std::string in;
    for (const auto& p : phones) in += fmt::format("{:.6f} {:.6f} {}\n", p.start_s, p.end_s, p.symbol == "AA" ? "AA1" : p.symbol);
    test::write_file(dir / "in.txt", in);
    const avsi::test::CliResult r = avsi::test::run_avsi("stream --model " + avsi::test::shell_quote((dir / "m.json").string()) +
                                                         " <" + avsi::test::shell_quote((dir / "in.txt").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::istringstream out(r.out);
    std::string line;
    std::getline(out, line);
    EXPECT_EQ(line.rfind("time_s,jaw_rotation,", 0), 0u);
    PhoneSequence stressed = phones;
    stressed[2].stressed = true;
    const auto batch = model.run_frames(stressed, frame_count(phones.back().end_s, 60.0));
    std::size_t k = 0;
    while (std::getline(out, line)) {
        ASSERT_LT(k, batch.size());
        std::stringstream ss(line);
        std::string cell;
        std::getline(ss, cell, ',');
        EXPECT_NEAR(std::stod(cell), k / 60.0, 1e-6);
        for (std::size_t p = 0; p < param_count; ++p) {
            std::getline(ss, cell, ',');
            EXPECT_NEAR(std::stod(cell), batch[k][p], 1e-6) << k << " " << p;
        }
        ++k;
    }
    EXPECT_EQ(k, batch.size());
}

}  // namespace
}  // namespace avsi::synth
