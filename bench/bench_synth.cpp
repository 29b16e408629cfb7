// Cohen-Massaro synthesis of a 60 s utterance at 60 fps for all 10
// parameters (target: <= 5 ms on one core). Run:
//   build-syn/bench/bench_synth --benchmark_filter=CohenMassaro
#include <benchmark/benchmark.h>

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

void CohenMassaroDefault60s60fps(benchmark::State& state) {
    const auto model = avsi::synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "cohen-massaro.json");
    const auto phones = random_utterance(60.0, 1);
    for (auto _ : state) {
        auto z = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(z.frames.data());
    }
    state.counters["segments"] = static_cast<double>(phones.size());
}
BENCHMARK(CohenMassaroDefault60s60fps)->Unit(benchmark::kMillisecond);

// The same with per-phone exponents c != 1 (pow instead of a product).
void CohenMassaroRandomC60s60fps(benchmark::State& state) {
    auto model = avsi::synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "cohen-massaro.json");
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

}  // namespace

BENCHMARK_MAIN();
