// Cohen-Massaro synthesis of a 60 s utterance at 60 fps for all 10
// parameters (target: <= 5 ms on one core), with the hand-set model
// (bench/data/cohen-massaro-handset.json: the make_defaults.py model of
// commit af04861, frozen here so the figure does not move with retraining;
// c = 1),
// with per-phone exponents c != 1, with c != 1 and a different θ and φ
// for every phone and parameter, with the current trained default model
// file (c = 1, rates down to the training floor of 10 s^−c: far-reaching
// tails, summed by the c = 1 recursions), and with any model file named by
// AVSI_BENCH_CM_MODEL. AVSI_CM_KERNEL=sse2 times the kernels without AVX2.
// Run:
//   taskset -c 0 build-syn/bench/bench_synth --benchmark_filter=CohenMassaro
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "avsi/core/rng.h"
#include "avsi/synth/cohen_massaro.h"

namespace {

avsi::PhoneSequence random_utterance(double duration_s, std::uint64_t seed) {
    static const char* symbols[] = {"AA", "AE", "AH", "IY", "UW", "OW", "EH", "P", "B", "M", "F", "V", "T", "D",
                                    "S", "Z", "K", "G", "N", "L", "R", "W", "SH", "TH", "HH", "sil"};
    avsi::Rng rng(seed);
    avsi::PhoneSequence phones;
    double t = 0.0;
    while (t < duration_s) {
        const double d = rng.uniform(0.05, 0.15);  // ~10 phones per second
        phones.push_back({symbols[rng.uniform_int(std::size(symbols))], t, t + d, rng.uniform() < 0.5});
        t += d;
    }
    return phones;
}

const std::filesystem::path handset_model =
    std::filesystem::path(AVSI_PROTOCOLS_DIR) / ".." / "bench" / "data" / "cohen-massaro-handset.json";

void CohenMassaroHandSet60s60fps(benchmark::State& state) {
    const auto model = avsi::synth::load_model(handset_model);
    const auto phones = random_utterance(60.0, 1);
    for (auto _ : state) {
        auto z = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(z.frames.data());
    }
    state.counters["segments"] = static_cast<double>(phones.size());
}
BENCHMARK(CohenMassaroHandSet60s60fps)->Unit(benchmark::kMillisecond);

// The same with per-phone exponents c != 1 (pow instead of a product).
void CohenMassaroRandomC60s60fps(benchmark::State& state) {
    auto model = avsi::synth::load_model(handset_model);
    auto* cm = dynamic_cast<avsi::synth::CohenMassaroModel*>(model.get());
    avsi::Rng rng(2);
    for (auto& [key, phone] : cm->phones()) phone.c = rng.uniform(0.7, 1.6);
    const auto phones = random_utterance(60.0, 1);
    for (auto _ : state) {
        auto z = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(z.frames.data());
    }
}
BENCHMARK(CohenMassaroRandomC60s60fps)->Unit(benchmark::kMillisecond);

// Per-phone c != 1 and per phone and parameter θ, φ in [15, 45] /s: no two
// parameters of a segment share a rate, so ten exponentials per segment and
// frame instead of one or two.
void CohenMassaroRandomCRates60s60fps(benchmark::State& state) {
    auto model = avsi::synth::load_model(handset_model);
    auto* cm = dynamic_cast<avsi::synth::CohenMassaroModel*>(model.get());
    avsi::Rng rng(3);
    for (auto& [key, phone] : cm->phones()) {
        phone.c = rng.uniform(0.7, 1.6);
        for (auto& q : phone.params) {
            q.theta_per_s = rng.uniform(15.0, 45.0);
            q.phi_per_s = rng.uniform(15.0, 45.0);
        }
    }
    const auto phones = random_utterance(60.0, 1);
    for (auto _ : state) {
        auto z = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(z.frames.data());
    }
}
BENCHMARK(CohenMassaroRandomCRates60s60fps)->Unit(benchmark::kMillisecond);

// The default model file as it is now (protocols/models/cohen-massaro.json).
void CohenMassaroDefaultFile60s60fps(benchmark::State& state) {
    const auto model = avsi::synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "cohen-massaro.json");
    const auto phones = random_utterance(60.0, 1);
    for (auto _ : state) {
        auto z = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(z.frames.data());
    }
}
BENCHMARK(CohenMassaroDefaultFile60s60fps)->Unit(benchmark::kMillisecond);

// Any Cohen-Massaro model file named by AVSI_BENCH_CM_MODEL (for comparing
// trained candidates, synth/README.md); skipped when unset.
void CohenMassaroEnvFile60s60fps(benchmark::State& state) {
    const char* path = std::getenv("AVSI_BENCH_CM_MODEL");
    if (!path || !*path) {
        state.SkipWithError("set AVSI_BENCH_CM_MODEL to a model file");
        return;
    }
    const auto model = avsi::synth::load_model(path);
    const auto phones = random_utterance(60.0, 1);
    for (auto _ : state) {
        auto z = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(z.frames.data());
    }
}
BENCHMARK(CohenMassaroEnvFile60s60fps)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
