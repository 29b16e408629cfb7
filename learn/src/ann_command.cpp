// `avsi train --model ann…` (Beskow §4.4–4.5): corpus loading and split,
// the trained model's provenance, and the look-ahead sweep's CSV and cairo
// SVG plot (Fig. 4). No torch here: training itself is in ann_training.cpp.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/learn/ann_training.h"
#include "avsi/learn/evaluation.h"
#include "svg_plot.h"

namespace avsi::learn {
namespace fs = std::filesystem;

std::pair<int, int> parse_lookahead_range(const std::string& text) {
    auto parse_int = [&](std::string_view s) {
        int v = 0;
        const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
        if (ec != std::errc() || ptr != s.data() + s.size() || s.empty())
            throw UsageError(fmt::format("--sweep-lookahead: expected FIRST..LAST (e.g. 0..15), got \"{}\"", text));
        return v;
    };
    const auto dots = text.find("..");
    if (dots == std::string::npos) {
        const int v = parse_int(text);
        return {v, v};
    }
    const int a = parse_int(std::string_view(text).substr(0, dots));
    const int b = parse_int(std::string_view(text).substr(dots + 2));
    if (a < 0 || b < a)
        throw UsageError(fmt::format("--sweep-lookahead: expected 0 <= FIRST <= LAST, got \"{}\"", text));
    return {a, b};
}

void write_lookahead_csv(const fs::path& path, const std::vector<LookaheadPoint>& points) {
    std::ostringstream out;
    out << "look_ahead,look_back,epochs,train_rmse_percent,test_rmse_percent,seconds\n";
    for (const auto& p : points)
        out << fmt::format("{},{},{},{:.6f},{:.6f},{:.3f}\n", p.look_ahead, p.look_back, p.epochs,
                           p.train_rmse_percent, p.test_rmse_percent, p.seconds);
    write_text_file(path, out.str());
}

void write_lookahead_svg(const fs::path& path, const std::vector<LookaheadPoint>& points) {
    if (points.empty()) throw InputError(Diagnostic{path.string(), 0, 0, "", "expected sweep points, got none"});
    const detail::PlotBox box{560, 360, 70, 20, 36, 52};
    detail::ValueRange range;
    for (const auto& p : points) range.extend(p.test_rmse_percent);
    const auto [lo, hi] = range.padded(0.08);
    const double a0 = points.front().look_ahead, a1 = std::max<double>(points.back().look_ahead, a0 + 1);
    detail::SvgPage page(path, box);
    auto X = [&](double a) { return page.x_of(a, a0, a1); };
    auto Y = [&](double v) { return page.y_of(v, lo, hi); };
    cairo_t* cr = page.cr();
    page.frame_with_value_labels(lo, hi, 50);
    for (const auto& p : points) page.text(X(p.look_ahead) - 4, box.height - box.bottom + 16, fmt::format("{}", p.look_ahead));
    page.text(box.left, 20, "Occlusion ANN: held-out RMSE (% of range) vs look-ahead (frames at 60 fps), window 31");
    page.text((box.width - box.left) / 2, box.height - 12, "look-ahead (frames)");
    cairo_set_source_rgb(cr, 0.1, 0.3, 0.8);
    cairo_set_line_width(cr, 1.5);
    page.polyline(
        points.size(), [&](std::size_t i) { return X(points[i].look_ahead); },
        [&](std::size_t i) { return Y(points[i].test_rmse_percent); });
    for (const auto& p : points) {
        cairo_arc(cr, X(p.look_ahead), Y(p.test_rmse_percent), 3, 0, 2 * M_PI);
        cairo_fill(cr);
    }
    page.finish();
}

void run_ann_command(const AnnCommandSettings& s) {
    if (s.out.empty()) throw UsageError("--out: expected the model file (or, for a sweep, the folder) to write");
    AnnTrainingSettings training = s.training;
    if (s.model == "ann" || s.model == "ann1")
        training.config = ann1_config();
    else if (s.model == "ann2")
        training.config = ann2_config();
    else
        throw UsageError(fmt::format("--model: expected ann, ann1 or ann2, got \"{}\"", s.model));
    training.config.fps = s.training.config.fps;
    if (s.look_ahead) training.config.look_ahead = *s.look_ahead;
    if (s.look_back) training.config.look_back = *s.look_back;
    if (training.config.look_ahead < 0 || training.config.look_back < 0)
        throw UsageError("--look-ahead/--look-back: expected frame counts >= 0");

    const ArticulatoryCorpus corpus = load_articulatory_corpus(s.corpus);
    const CorpusSplit split = split_corpus(corpus, SplitSettings{s.split_seed, s.test_fraction});
    const auto train = load_corpus_utterances(corpus, split.train_ids);
    const auto test = load_corpus_utterances(corpus, split.test_ids);
    const std::string split_text = fmt::format("{} train / {} test, seed {}, test fraction {}", split.train_ids.size(),
                                               split.test_ids.size(), split.seed, split.test_fraction);
    log_info("training ANN ({}) on {} ({})", s.model, corpus.name, split_text);

    if (!s.sweep.empty()) {
        const auto [first, last] = parse_lookahead_range(s.sweep);
        const auto points = sweep_lookahead(training, first, last, s.sweep_window, train, test);
        fs::create_directories(s.out);
        write_lookahead_csv(s.out / "lookahead.csv", points);
        write_lookahead_svg(s.out / "lookahead.svg", points);
        log_info("wrote {} and {}", (s.out / "lookahead.csv").string(), (s.out / "lookahead.svg").string());
        return;
    }

    AnnTrainingReport report = train_ann(training, train, test);
    // Table-2 style scores of the trained model (non-silence frames).
    const AnnModel& model = *report.model;
    const NamedPredictor predictor{"ann", [&model](const PhoneSequence& p, std::span<const double> t,
                                                   std::vector<Frame>& out) { model.evaluate(p, t, out); }};
    const ModelScores train_scores = evaluate_predictors(train, {predictor}).front();
    const ModelScores test_scores =
        test.empty() ? train_scores : evaluate_predictors(test, {predictor}).front();
    const auto all = static_cast<std::size_t>(FrameSubset::AllNonSilence);

    ModelProvenance prov;
    prov.method = "trained";
    prov.data = fmt::format("{} (sha256 {})", corpus.name, corpus.hash);
    prov.split = split_text;
    prov.errors = {{"train_rmse_percent", train_scores.mean[all].rmse_percent},
                   {"test_rmse_percent", test_scores.mean[all].rmse_percent},
                   {"train_pearson", train_scores.mean[all].pearson},
                   {"test_pearson", test_scores.mean[all].pearson},
                   {"training_seconds", report.seconds}};
    prov.notes = fmt::format(
        "Trained by `avsi train --model {}` (libtorch BPTT over {}, Adam lr {}, batches of {}, seed {}, {} thread(s); early stopping on the test split with patience {}, at most {} epochs): "
        "{:.1f} s. Errors are RMSE in % of range and Pearson rho, mean over parameters, non-silence frames.",
        s.model,
        training.chunk_frames > 0
            ? fmt::format("{}-frame chunks after {} warm-up frames", training.chunk_frames, training.warmup_frames)
            : std::string("whole utterances"),
        training.learning_rate, training.batch_utterances, training.seed, training.threads,
        training.patience, training.max_epochs, report.seconds);
    nlohmann::json facts = nlohmann::json::object();
    facts["corpus"] = corpus.name;
    facts["corpus_sha256"] = corpus.hash;
    facts["split"] = split_text;
    facts["seed"] = training.seed;
    facts["chunk_frames"] = training.chunk_frames;
    facts["warmup_frames"] = training.warmup_frames;
    facts["batch"] = training.batch_utterances;
    facts["learning_rate"] = training.learning_rate;
    facts["max_epochs"] = training.max_epochs;
    facts["patience"] = training.patience;
    facts["max_seconds_per_network"] = training.max_seconds;
    facts["seconds"] = report.seconds;
    nlohmann::json nets = nlohmann::json::array();
    for (const auto& n : report.networks)
        nets.push_back({{"name", n.name},
                        {"epochs", n.epochs},
                        {"best_epoch", n.best_epoch},
                        {"train_rmse_percent", n.train_rmse_percent},
                        {"test_rmse_percent", n.test_rmse_percent},
                        {"seconds", n.seconds}});
    facts["networks"] = nets;
    report.model->training_json = facts.dump();
    report.model->set_provenance(prov);
    save_model(*report.model, s.out);
    log_info("wrote {}: test RMSE {:.2f} % of range, test rho {:.3f}, {:.1f} s", s.out.string(),
             test_scores.mean[all].rmse_percent, test_scores.mean[all].pearson, report.seconds);
}

}  // namespace avsi::learn
