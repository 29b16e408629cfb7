// Training benchmark (issue 4): Cohen-Massaro trained on 200 utterances of the
// synthetic reference speaker, early-stopping on the rest, on 2 threads.
// The corpus is generated once into a temporary folder (espeak-ng timing),
// or read from AVSI_BENCH_CORPUS (a folder written by `avsi corpus reference`).
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "avsi/synth/articulatory_corpus.h"
#include "avsi/synth/reference_speaker.h"
#include "avsi/synth/training.h"

namespace {

struct Data {
    std::vector<avsi::synth::CorpusUtterance> train, test;
};

const Data& data() {
    static const Data d = [] {
        const char* given = std::getenv("AVSI_BENCH_CORPUS");
        auto dir = std::filesystem::temp_directory_path() / "avsi_bench_training_corpus";
        if (given && *given) {
            dir = given;
        } else {
            std::filesystem::remove_all(dir);
            avsi::synth::write_reference_corpus(dir, {});
        }
        const auto corpus = avsi::synth::load_articulatory_corpus(dir);
        std::vector<std::string> ids;
        for (const auto& e : corpus.entries) ids.push_back(e.id);
        auto all = avsi::synth::load_corpus_utterances(corpus, ids);
        Data out;
        out.train.assign(all.begin(), all.begin() + 200);
        out.test.assign(all.begin() + 200, all.end());
        return out;
    }();
    return d;
}

void BM_TrainCohenMassaro200(benchmark::State& state) {
    const Data& d = data();
    avsi::synth::TrainingSettings settings;
    settings.model = "cohen-massaro";
    settings.threads = static_cast<int>(state.range(0));
    for (auto _ : state) {
        const auto report = avsi::synth::train_model(settings, d.train, d.test);
        state.counters["iterations"] = report.iterations;
        state.counters["test_rmse_percent"] = report.test_rmse_percent;
        benchmark::DoNotOptimize(report.model.get());
    }
}
BENCHMARK(BM_TrainCohenMassaro200)->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
