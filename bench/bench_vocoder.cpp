// Vocoder and STOI throughput. The target (issue 6): 3-band vocoding of 60 s
// of 22.05 kHz audio at least 1000× faster than real time on one core
// (under 60 ms per iteration). Run: build-<name>/bench/bench_vocoder
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "avsi/core/rng.h"
#include "avsi/vocoder/vocoder.h"

namespace {

// 60 s of a syllable-rate modulated harmonic complex plus noise at 22.05 kHz.
std::vector<double> test_signal(double rate_hz, double duration_s) {
    const auto n = static_cast<std::size_t>(rate_hz * duration_s);
    std::vector<double> x(n);
    avsi::Rng rng(1);
    for (std::size_t i = 0; i < n; ++i) {
        const double t = static_cast<double>(i) / rate_hz;
        double v = 0.0;
        for (int k = 1; k <= 20; ++k) v += std::sin(2 * std::numbers::pi * 120.0 * k * t) / k;
        x[i] = 0.05 * (1.0 - std::cos(2 * std::numbers::pi * 4.0 * t)) * v + 0.01 * rng.normal();
    }
    return x;
}

void vocode_60s(benchmark::State& state, avsi::vocoder::VocoderSettings settings) {
    const double rate = 22050.0;
    const double duration_s = 60.0;
    const std::vector<double> x = test_signal(rate, duration_s);
    settings.bands = static_cast<int>(state.range(0));
    for (auto _ : state) {
        auto out = avsi::vocoder::vocode_channel(x, rate, settings);
        benchmark::DoNotOptimize(out.samples.data());
    }
    // Seconds of audio per second of processing = the real-time factor.
    state.counters["x_realtime"] = benchmark::Counter(duration_s * static_cast<double>(state.iterations()),
                                                      benchmark::Counter::kIsRate);
}

void BM_Vocode60s_Default(benchmark::State& state) { vocode_60s(state, {}); }
BENCHMARK(BM_Vocode60s_Default)->Arg(3)->Arg(8)->Arg(16)->Unit(benchmark::kMillisecond);

void BM_Vocode60s_ZeroPhaseSine(benchmark::State& state) {
    avsi::vocoder::VocoderSettings s;
    s.zero_phase = true;
    s.carrier = avsi::vocoder::CarrierType::Sine;
    vocode_60s(state, s);
}
BENCHMARK(BM_Vocode60s_ZeroPhaseSine)->Arg(3)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
