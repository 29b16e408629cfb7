// Training benchmark (issue 4): Cohen-Massaro trained on 200 utterances of the
// synthetic reference speaker, early-stopping on the rest, on 2 threads.
// The corpus is generated once into a temporary folder (espeak-ng timing),
// or read from AVSI_BENCH_CORPUS (a folder written by `avsi corpus reference`).
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "avsi/learn/articulatory_corpus.h"
#include "avsi/learn/reference_speaker.h"
#include "avsi/learn/training.h"

namespace {

struct Data {
    std::vector<avsi::learn::CorpusUtterance> train, test;
};

const Data& data() {
    static const Data d = [] {
        const char* given = std::getenv("AVSI_BENCH_CORPUS");
        auto dir = std::filesystem::temp_directory_path() / "avsi_bench_training_corpus";
        if (given && *given) {
            dir = given;
        } else {
            std::filesystem::remove_all(dir);
            avsi::learn::write_reference_corpus(dir, {});
        }
        const auto corpus = avsi::learn::load_articulatory_corpus(dir);
        std::vector<std::string> ids;
        for (const auto& e : corpus.entries) ids.push_back(e.id);
        auto all = avsi::learn::load_corpus_utterances(corpus, ids);
        Data out;
        out.train.assign(all.begin(), all.begin() + 200);
        out.test.assign(all.begin() + 200, all.end());
        return out;
    }();
    return d;
}

void BM_TrainCohenMassaro200(benchmark::State& state) {
    const Data& d = data();
    avsi::learn::TrainingSettings settings;
    settings.model = "cohen-massaro";
    settings.threads = static_cast<int>(state.range(0));
    for (auto _ : state) {
        const auto report = avsi::learn::train_model(settings, d.train, d.test);
        state.counters["iterations"] = report.iterations;
        state.counters["test_rmse_percent"] = report.test_rmse_percent;
        benchmark::DoNotOptimize(report.model.get());
    }
}
BENCHMARK(BM_TrainCohenMassaro200)->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

// The rate floor (TrainingSettings::min_rate_per_s, Arg = floor × 10 in
// s^−c) against held-out error on the corpus' own split (186 train / 80 test
// for the reference corpus, as `avsi train` uses it), on 2 threads: the
// evidence for the default floor. Needs AVSI_BENCH_CORPUS.
void BM_TrainCohenMassaroRateFloor(benchmark::State& state) {
    const char* given = std::getenv("AVSI_BENCH_CORPUS");
    if (!given || !*given) {
        state.SkipWithError("set AVSI_BENCH_CORPUS to a folder written by avsi corpus reference");
        return;
    }
    const auto corpus = avsi::learn::load_articulatory_corpus(given);
    const auto split = avsi::learn::split_corpus(corpus);
    const auto train = avsi::learn::load_corpus_utterances(corpus, split.train_ids);
    const auto test = avsi::learn::load_corpus_utterances(corpus, split.test_ids);
    avsi::learn::TrainingSettings settings;
    settings.model = "cohen-massaro";
    settings.threads = 2;
    settings.min_rate_per_s = static_cast<double>(state.range(0)) / 10.0;
    for (auto _ : state) {
        const auto report = avsi::learn::train_model(settings, train, test);
        state.counters["min_rate_per_s"] = settings.min_rate_per_s;
        state.counters["iterations"] = report.iterations;
        state.counters["train_rmse_percent"] = report.train_rmse_percent;
        state.counters["test_rmse_percent"] = report.test_rmse_percent;
        state.counters["test_pearson"] = report.test_pearson;
        benchmark::DoNotOptimize(report.model.get());
    }
}
BENCHMARK(BM_TrainCohenMassaroRateFloor)
    ->Arg(1)->Arg(20)->Arg(50)->Arg(100)->Arg(200)
    ->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
