// ANN control model inference speed (Beskow §4.4–4.5, synth/ann.h): the
// default ANN 1 and ANN 2 (protocols/models/ann1.json, ann2.json) on a 60 s
// utterance at 60 fps, batch and streamed. The "x_realtime" counter is
// seconds of speech per second of compute; the goal is ≥ 100 on one core.
// Run with one core, e.g. `taskset -c 0 build-ann/bench/bench_ann`.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "avsi/synth/ann.h"

namespace {

using namespace avsi;
using namespace avsi::synth;

PhoneSequence minute_of_phones() {
    static const char* symbols[] = {"AA", "P", "IY", "M", "UW", "S", "F", "EH", "B", "OW", "T", "L", "sil"};
    std::mt19937 rng(1);
    std::uniform_int_distribution<int> pick(0, 12);
    std::uniform_real_distribution<double> dur(0.05, 0.2);
    PhoneSequence out;
    double t = 0;
    while (t < 60.0) {
        const double d = dur(rng);
        out.push_back(Phone{symbols[pick(rng)], t, t + d, true});
        t += d;
    }
    return out;
}

std::unique_ptr<ControlModel> load(const char* name) {
    return load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / name);
}

void run_batch(benchmark::State& state, const char* name) {
    const auto model = load(name);
    const PhoneSequence phones = minute_of_phones();
    for (auto _ : state) {
        Trajectory t = model->synthesize(phones, 60.0);
        benchmark::DoNotOptimize(t.frames.data());
    }
    state.counters["x_realtime"] =
        benchmark::Counter(phones.back().end_s * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_Ann1Batch(benchmark::State& state) { run_batch(state, "ann1.json"); }
void BM_Ann2Batch(benchmark::State& state) { run_batch(state, "ann2.json"); }

void BM_Ann2Streamed(benchmark::State& state) {
    const auto model = load("ann2.json");
    const auto* ann = dynamic_cast<const AnnModel*>(model.get());
    const PhoneSequence phones = minute_of_phones();
    for (auto _ : state) {
        AnnStreamer s(*ann);
        std::size_t frames = 0;
        for (const auto& p : phones) {
            s.push(p);
            frames += s.take_ready().size();
        }
        s.finish();
        frames += s.take_ready().size();
        benchmark::DoNotOptimize(frames);
    }
    state.counters["x_realtime"] =
        benchmark::Counter(phones.back().end_s * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK(BM_Ann1Batch)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Ann2Batch)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Ann2Streamed)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
