// `avsi corpus fit-markers` → `avsi train` → `avsi evaluate`: four synthetic
// C3D recordings of the built-in head's markers (tests/learn/
// synthetic_markers.h) with phone labels become a parameter-track corpus
// whose tracks match the known ones, with a residual report and plot; a
// control model trains on it and Table 2 scores every parameter. The same
// recording fitted to the built-in head exported as glTF gives a second
// track.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/files.h"
#include "avsi/learn/articulatory_corpus.h"
#include "avsi/stimuli/gltf_head.h"
#include "avsi/stimuli/head.h"
#include "avsi/stimuli/marker_layout.h"
#include "c3d_test_writer.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"
#include "synthetic_markers.h"

namespace fs = std::filesystem;
using namespace avsi;

namespace {

const stimuli::Head& builtin_head() {
    static const stimuli::Head head = stimuli::load_default_head();
    return head;
}

// Writes recording `k` (its own seed and head motion) as a float MIPS C3D and
// its labels; returns the known tracks.
std::vector<synth::Frame> write_recording(const fs::path& dir, int k, std::size_t frames) {
    const auto model = stimuli::load_marker_model(builtin_head(), stimuli::default_marker_layout());
    test::SyntheticMarkerSpec spec;
    spec.frames = frames;
    spec.seed = 100 + k;
    spec.noise_mm = 0.0;  // the fit's accuracy under noise is marker_fit_test's; here the path is checked
    std::vector<synth::Frame> truth;
    const learn::MarkerRecording rec = test::synthetic_recording(model, spec, truth);
    test::C3dWriteSpec c3d;
    c3d.cpu = test::C3dCpu::Mips;
    c3d.floats = true;
    c3d.labels = rec.labels;
    c3d.frames = rec.frames;
    c3d.xyz = rec.xyz;
    test::write_c3d_file(dir / fmt::format("take{}.c3d", k), c3d);
    std::string labels = "start_s\tend_s\tphone\n";
    const char* phones[] = {"sil", "AA1", "M", "IY1", "P", "UW1", "F", "S"};
    const double duration = double(frames) / spec.rate_hz;
    for (int i = 0; 0.25 * i < duration - 1e-9; ++i)
        labels += fmt::format("{:.3f}\t{:.3f}\t{}\n", 0.25 * i, std::min(duration, 0.25 * (i + 1)), phones[(i + k) % 8]);
    write_text_file(dir / fmt::format("take{}.tsv", k), labels);
    return truth;
}

double worst_error(const learn::ParamTrack& fitted, const std::vector<synth::Frame>& truth) {
    double worst = 0;
    for (std::size_t f = 0; f < truth.size(); ++f)
        for (std::size_t j = 0; j < synth::param_count; ++j)
            worst = std::max(worst, std::abs(fitted.frames[f][j] - truth[f][j]));
    return worst;
}

}  // namespace

TEST(MarkerCorpus, FitTrainAndEvaluateOnOpticalRecordings) {
    const fs::path dir = test::temp_dir("marker_corpus");
    std::vector<std::vector<synth::Frame>> truth;
    std::string list = "id,markers,labels,split\n";
    for (int k = 0; k < 4; ++k) {
        truth.push_back(write_recording(dir, k, 180));
        list += fmt::format("take{0},take{0}.c3d,take{0}.tsv,{1}\n", k, k == 3 ? "test" : "train");
    }
    write_text_file(dir / "recordings.csv", list);
    const fs::path corpus = dir / "corpus";
    auto r = test::run_avsi({"corpus", "fit-markers", (dir / "recordings.csv").string(), "--out", corpus.string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    // The corpus's tracks are the known ones (noise-free markers: as the fit's own test, 0.03).
    for (int k = 0; k < 4; ++k) {
        const auto track = learn::read_param_track_csv(corpus / "tracks" / fmt::format("take{}.csv", k));
        ASSERT_EQ(track.size(), truth[k].size());
        EXPECT_LT(worst_error(track, truth[k]), 0.03) << k;
    }
    // The report has each recording's residual table and plot.
    const std::string report = read_text_file(corpus / "fit" / "report.md");
    EXPECT_NE(report.find("## take2"), std::string::npos);
    EXPECT_NE(report.find("| LL_C |"), std::string::npos);
    EXPECT_TRUE(fs::exists(corpus / "fit" / "take2.residual.svg"));
    const CsvTable residuals = read_csv(corpus / "fit" / "take2.residual.csv");
    EXPECT_EQ(residuals.rows.size(), 180u);
    EXPECT_EQ(residuals.header.size(), 31u);
    // Train a model on it and score it.
    r = test::run_avsi({"train", "--model", "cohen-massaro", "--corpus", corpus.string(), "--out",
                        (dir / "cm.json").string(), "--max-iterations", "5", "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    r = test::run_avsi({"evaluate", "--corpus", corpus.string(), "--models", (dir / "cm.json").string(), "--out",
                        (dir / "table").string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const CsvTable table = read_csv(dir / "table.csv");
    std::set<std::string> scored;
    const std::size_t c_param = table.require_column("parameter"), c_rmse = table.require_column("rmse_percent");
    for (const auto& row : table.rows)
        if (parse_double(row.fields[c_rmse])) scored.insert(row.fields[c_param]);
    for (const auto& info : synth::params()) EXPECT_TRUE(scored.count(std::string(info.name))) << info.name;
}

TEST(MarkerCorpus, OneRecordingFitsTheBuiltInHeadAndItsGltfExport) {
    const fs::path dir = test::temp_dir("marker_corpus_gltf");
    write_recording(dir, 0, 120);
    write_text_file(dir / "recordings.csv", "id,markers,labels\ntake0,take0.c3d,take0.tsv\n");
    stimuli::export_gltf_head(builtin_head(), dir / "head.glb");
    auto r = test::run_avsi({"corpus", "fit-markers", (dir / "recordings.csv").string(), "--out", (dir / "a").string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    r = test::run_avsi({"corpus", "fit-markers", (dir / "recordings.csv").string(), "--out", (dir / "b").string(),
                        "--head", (dir / "head.glb").string(), "--layout",
                        (stimuli::default_marker_layout().parent_path() / "markers-near.json").string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const auto a = learn::read_param_track_csv(dir / "a" / "tracks" / "take0.csv");
    const auto b = learn::read_param_track_csv(dir / "b" / "tracks" / "take0.csv");
    ASSERT_EQ(a.size(), b.size());
    // Both heads follow the recording: the jaw opens and closes alike (the
    // glTF rig is the blendshape rendering of the same rig, so the tracks
    // correlate closely without being equal).
    const std::size_t j = synth::index(synth::Param::JawRotation);
    double sa = 0, sb = 0, sab = 0, saa = 0, sbb = 0;
    const double n = double(a.size());
    for (std::size_t f = 0; f < a.size(); ++f) {
        const double x = a.frames[f][j], y = b.frames[f][j];
        sa += x, sb += y, sab += x * y, saa += x * x, sbb += y * y;
    }
    const double rho = (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
    EXPECT_GT(rho, 0.95);
    const std::string report = read_text_file(dir / "b" / "fit" / "report.md");
    EXPECT_NE(report.find("head.glb"), std::string::npos);
}
