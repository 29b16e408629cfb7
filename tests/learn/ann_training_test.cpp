// ANN training (libtorch BPTT) on a few synthetic utterances: seeded
// reproducibility, masking of missing parameters, learning, and the model
// file round trip (Beskow §4.4–4.5).
#include <gtest/gtest.h>

#include <cmath>

#include "ann_corpus_util.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/learn/ann_training.h"
#include "avsi/learn/evaluation.h"

namespace avsi::learn {
namespace {

struct TinyData {
    std::vector<CorpusUtterance> train, test;
};

const TinyData& tiny_data() {
    static const TinyData d = [] {
        TinyData out;
        for (unsigned i = 0; i < 8; ++i) out.train.push_back(synth::test::synthetic_utterance(100 + i, 10));
        for (unsigned i = 0; i < 3; ++i) out.test.push_back(synth::test::synthetic_utterance(200 + i, 10));
        return out;
    }();
    return d;
}

AnnTrainingSettings tiny_settings(int epochs = 4) {
    AnnTrainingSettings s;
    s.config = AnnConfig{60.0, 2, 3, 2};
    s.groups = ann_groups();
    for (auto& g : s.groups) g.hidden = 6;
    s.max_epochs = epochs;
    s.patience = 100;
    s.batch_utterances = 4;
    s.chunk_frames = 0;
    s.learning_rate = 0.02;
    s.seed = 17;
    return s;
}

TEST(AnnTraining, SameSeedGivesSameWeightsOtherSeedOthers) {
    const auto& d = tiny_data();
    const AnnTrainingReport a = train_ann(tiny_settings(), d.train, d.test);
    const AnnTrainingReport b = train_ann(tiny_settings(), d.train, d.test);
    AnnTrainingSettings other = tiny_settings();
    other.seed = 18;
    const AnnTrainingReport c = train_ann(other, d.train, d.test);
    ASSERT_EQ(a.model->networks().size(), b.model->networks().size());
    for (std::size_t i = 0; i < a.model->networks().size(); ++i) {
        EXPECT_EQ(a.model->networks()[i].W, b.model->networks()[i].W);
        EXPECT_EQ(a.model->networks()[i].U, b.model->networks()[i].U);
        EXPECT_EQ(a.model->networks()[i].V, b.model->networks()[i].V);
        EXPECT_EQ(a.model->networks()[i].c, b.model->networks()[i].c);
    }
    EXPECT_NE(a.model->networks()[0].W, c.model->networks()[0].W);
}

TEST(AnnTraining, GroupsWithoutDataAreLeftOutAndMissingValuesMasked) {
    const auto& d = tiny_data();
    const AnnTrainingReport r = train_ann(tiny_settings(2), d.train, d.test);
    // Only jaw_rotation and upper_lip_raise are present: the occlusion network.
    ASSERT_EQ(r.model->networks().size(), 1u);
    EXPECT_EQ(r.model->networks()[0].group.name, "occlusion");
    for (const auto& n : r.networks) {
        EXPECT_TRUE(std::isfinite(n.train_rmse_percent));
        EXPECT_TRUE(std::isfinite(n.test_rmse_percent));
    }
    for (float w : r.model->networks()[0].W) ASSERT_TRUE(std::isfinite(w));
}

TEST(AnnTraining, LearnsTheSyntheticMappingAndStopsEarly) {
    const auto& d = tiny_data();
    AnnTrainingSettings s = tiny_settings(60);
    s.patience = 5;
    s.chunk_frames = 30;   // truncated BPTT with warm-up
    s.warmup_frames = 10;
    const AnnTrainingReport r = train_ann(s, d.train, d.test);
    const AnnNetworkReport& n = r.networks.front();
    // The kept epoch has the minimum held-out error of the curve.
    ASSERT_FALSE(n.test_curve.empty());
    const double min_curve = *std::min_element(n.test_curve.begin(), n.test_curve.end());
    EXPECT_DOUBLE_EQ(n.test_rmse_percent, min_curve);
    EXPECT_EQ(n.test_curve[static_cast<std::size_t>(n.best_epoch - 1)], min_curve);
    if (n.epochs < s.max_epochs) {
        EXPECT_EQ(n.epochs - n.best_epoch, s.patience);
    }
    // Much better than the first epoch and than always predicting neutral.
    EXPECT_LT(n.test_rmse_percent, 0.7 * n.test_curve.front());
    const AnnModel& model = *r.model;
    const auto scores = evaluate_predictors(
        d.test, {{"ann", [&](const PhoneSequence& p, std::span<const double> t, std::vector<Frame>& o) {
                      model.evaluate(p, t, o);
                  }},
                 {"neutral", [](const PhoneSequence&, std::span<const double> t, std::vector<Frame>& o) {
                      o.assign(t.size(), Frame{});
                  }}});
    const auto all = static_cast<std::size_t>(FrameSubset::AllNonSilence);
    EXPECT_LT(scores[0].mean[all].rmse_percent, 0.5 * scores[1].mean[all].rmse_percent);
    EXPECT_GT(scores[0].mean[all].pearson, 0.8);
}

TEST(AnnModelFile, SaveLoadRoundTripGivesIdenticalOutput) {
    const auto& d = tiny_data();
    AnnTrainingReport r = train_ann(tiny_settings(2), d.train, d.test);
    r.model->training_json = R"({"note":"tiny"})";
    ModelProvenance p;
    p.method = "trained";
    p.data = "synthetic";
    p.errors = {{"test_rmse_percent", r.networks[0].test_rmse_percent}};
    r.model->set_provenance(p);
    const auto dir = synth::test::temp_dir("ann_roundtrip");
    save_model(*r.model, dir / "m.json");
    const auto loaded = load_model(dir / "m.json");
    ASSERT_EQ(loaded->kind(), "ann");
    EXPECT_EQ(loaded->to_json_text(), r.model->to_json_text());
    EXPECT_EQ(loaded->provenance().data, "synthetic");
    const PhoneSequence phones = synth::test::random_phones(9, 15);
    const Trajectory a = r.model->synthesize(phones, 60.0);
    const Trajectory b = loaded->synthesize(phones, 60.0);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a.frames[k], b.frames[k]) << k;
}

TEST(AnnModelFile, BadFilesNameTheField) {
    const auto dir = synth::test::temp_dir("ann_bad");
    const AnnModel m = synth::test::random_ann(AnnConfig{60.0, 1, 1, 2}, 3, 4);
    std::string text = m.to_json_text();
    // Truncate one weight blob: wrong size.
    const auto pos = text.find("\"c\": \"");
    ASSERT_NE(pos, std::string::npos);
    synth::test::write_file(dir / "short.json", text.substr(0, pos + 6) + "AAAA" + text.substr(text.find('"', pos + 6)));
    try {
        load_model(dir / "short.json");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("/networks/0"), std::string::npos) << e.what();
    }
    std::string bad_param = text;
    bad_param.replace(bad_param.find("jaw_rotation"), 12, "jaw_rotaton");
    synth::test::write_file(dir / "param.json", bad_param);
    EXPECT_THROW(load_model(dir / "param.json"), InputError);
}

TEST(AnnLookahead, RangeParsing) {
    EXPECT_EQ(parse_lookahead_range("0..15"), std::make_pair(0, 15));
    EXPECT_EQ(parse_lookahead_range("3"), std::make_pair(3, 3));
    EXPECT_THROW(parse_lookahead_range("5..2"), UsageError);
    EXPECT_THROW(parse_lookahead_range("a..2"), UsageError);
}

TEST(AnnLookahead, SweepWritesOnePointPerLookAhead) {
    const auto& d = tiny_data();
    AnnTrainingSettings s = tiny_settings(2);
    const auto points = sweep_lookahead(s, 0, 2, 5, d.train, d.test);
    ASSERT_EQ(points.size(), 3u);
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(points[static_cast<std::size_t>(a)].look_ahead, a);
        EXPECT_EQ(points[static_cast<std::size_t>(a)].look_back, 4 - a);
    }
    const auto dir = synth::test::temp_dir("ann_sweep");
    write_lookahead_csv(dir / "la.csv", points);
    write_lookahead_svg(dir / "la.svg", points);
    const std::string csv = read_text_file(dir / "la.csv");
    EXPECT_EQ(csv.rfind("look_ahead,look_back,epochs,train_rmse_percent,test_rmse_percent,seconds\n", 0), 0u);
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 4);
    EXPECT_NE(read_text_file(dir / "la.svg").find("<svg"), std::string::npos);
}

}  // namespace
}  // namespace avsi::learn
