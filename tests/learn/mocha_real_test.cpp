// The real-data path end to end: one real MOCHA-TIMIT utterance
// (../shared/testdata/ema/mocha, fsew0_001: EMA at 500 Hz, MOCHA labels)
// read, mapped to the parameters with head-motion removal, trained on with
// `avsi train` and scored with `avsi evaluate`, as docs/articulography.md
// tells a lab holding the full database to do.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "avsi/core/csv.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"
#include "avsi/learn/articulatory_corpus.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::learn;

namespace {

const fs::path mocha_dir = fs::path(AVSI_SHARED_DIR) / "testdata" / "ema" / "mocha";

// A corpus of the one real utterance, as a lab writes one for the database.
fs::path write_real_corpus(const fs::path& dir) {
    for (const char* f : {"fsew0_001.ema", "fsew0_001.lab"}) fs::copy_file(mocha_dir / f, dir / f);
    write_text_file(dir / "corpus.json", R"({"format": "avsi-articulatory-corpus", "version": 1, "name": "mocha-fsew0-sample",
 "sensor_mapping": {"preset": "mocha"},
 "utterances": [{"id": "fsew0_001", "track": "fsew0_001.ema", "labels": "fsew0_001.lab", "split": "train"}]})");
    return dir;
}

}  // namespace

TEST(MochaReal, TrainAndEvaluateOnARealUtterance) {
    if (!fs::exists(mocha_dir / "fsew0_001.ema")) GTEST_SKIP() << "no " << mocha_dir << " (../shared beside the checkout)";
    const fs::path dir = write_real_corpus(test::temp_dir("mocha_real"));
    const fs::path out = dir / "out";
    fs::create_directories(out);

    // Read and mapped: a real track, not synthetic; the drivable parameters present and in range.
    const ArticulatoryCorpus corpus = load_articulatory_corpus(dir);
    EXPECT_FALSE(corpus.synthetic);
    const CorpusUtterance u = load_corpus_utterance(corpus, corpus.entries.front());
    EXPECT_GT(u.track.size(), 100u);
    EXPECT_TRUE(u.track.present[static_cast<std::size_t>(synth::Param::JawRotation)]);
    EXPECT_FALSE(u.track.present[static_cast<std::size_t>(synth::Param::JawShift)]);
    double jaw_min = 1e9, jaw_max = -1e9;
    for (const auto& f : u.track.frames) {
        const double jaw = f[static_cast<std::size_t>(synth::Param::JawRotation)];
        if (!std::isfinite(jaw)) continue;
        jaw_min = std::min(jaw_min, jaw);
        jaw_max = std::max(jaw_max, jaw);
    }
    EXPECT_GT(jaw_max - jaw_min, 0.1) << "the jaw moves in running speech";
    EXPECT_GT(jaw_min, -0.5);
    EXPECT_LT(jaw_max, 1.5);

    // Trained: the Cohen-Massaro model on the utterance.
    auto r = test::run_avsi({"train", "--model", "cohen-massaro", "--corpus", dir.string(), "--out",
                             (out / "cm.json").string(), "--max-iterations", "10", "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    const auto model = nlohmann::json::parse(read_text_file(out / "cm.json"));
    EXPECT_NE(model.dump().find("mocha-fsew0-sample"), std::string::npos) << "the provenance names the corpus";

    // Scored: Table 2 columns for the drivable parameters, no "synthetic" caveat.
    r = test::run_avsi({"evaluate", "--subset", "all", "--corpus", dir.string(), "--models", (out / "cm.json").string(),
                        (fs::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json").string(), "--out",
                        (out / "table").string()});
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    EXPECT_EQ(r.out.find("This corpus is synthetic"), std::string::npos);
    const CsvTable t = read_csv(out / "table.csv");
    const std::size_t c_model = t.require_column("model"), c_subset = t.require_column("subset"),
                      c_param = t.require_column("parameter"), c_rmse = t.require_column("rmse_percent");
    double cm_mean = NAN, rule_mean = NAN;
    for (const auto& row : t.rows) {
        if (row.fields[c_subset] != "all non-silence" || row.fields[c_param] != "mean") continue;
        const auto v = parse_double(row.fields[c_rmse]);
        ASSERT_TRUE(v.has_value()) << row.fields[c_rmse];
        (row.fields[c_model] == "cm" ? cm_mean : rule_mean) = *v;
    }
    EXPECT_TRUE(std::isfinite(cm_mean) && std::isfinite(rule_mean));
    // Fitted to this utterance, the trained model follows it more closely than the hand-set rules.
    EXPECT_LT(cm_mean, rule_mean);
    fs::remove_all(dir);
}
