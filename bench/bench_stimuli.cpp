// Stimulus rendering speed: posing, rendering (OSMesa llvmpipe, 640×480) with
// the default settings (per-vertex Blinn-Phong + FXAA, the static part of the
// head drawn once and reused) and the costlier options (per-pixel lighting,
// 4× MSAA, no static-part cache), H.264 encoding, and render + encode
// together in frames/s — on one thread and on one worker per core, as the
// stimulus builder runs (each worker its own renderer and encoder).
// Run: build-stim/bench/bench_stimuli --benchmark_counters_tabular=true
// With one worker per core, set LP_NUM_THREADS=0 as build-stimuli does (the
// rasteriser's thread count is read once per process):
//   LP_NUM_THREADS=0 build-stim/bench/bench_stimuli --benchmark_filter="RenderEncodeWorkers|BM_Render/0|BM_Encode" --benchmark_min_time=3
// Each result carries the 1-minute load average at its end (load_1min):
// figures measured while other work runs are pessimistic.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/stimuli/video.h"

namespace {

using namespace avsi::stimuli;

// The 1-minute load average, to report next to every figure.
double load_1min() {
    double load[1] = {0.0};
    return getloadavg(load, 1) == 1 ? load[0] : -1.0;
}

const Head& head() {
    static const Head h = load_default_head();
    return h;
}

Pose moving_pose(std::int64_t k) {
    Pose p;
    p.params[0] = 0.5 + 0.5 * std::sin(0.3 * double(k));
    p.params[1] = 0.5 * std::cos(0.2 * double(k));
    p.params[2] = 0.3 * std::sin(0.17 * double(k));
    return p;
}

// range(0): 0 = defaults, 1 = per-pixel lighting, 2 = 4x MSAA without FXAA, 3 = no anti-aliasing,
// 4 = defaults without the static-part cache (every triangle drawn, every pixel anti-aliased).
RenderSettings variant(std::int64_t v) {
    RenderSettings rs;
    if (v == 1) rs.per_pixel_lighting = true;
    if (v == 2) rs.samples = 4, rs.fxaa = false;
    if (v == 3) rs.fxaa = false;
    if (v == 4) rs.cache_static = false;
    return rs;
}

const char* variant_name(std::int64_t v) {
    switch (v) {
        case 1: return "per-pixel lighting + FXAA";
        case 2: return "per-vertex lighting + 4x MSAA";
        case 3: return "per-vertex lighting, no AA";
        case 4: return "default without the static-part cache";
        default: return "default: per-vertex lighting + FXAA";
    }
}

void BM_Pose(benchmark::State& state) {
    PosedMesh posed;
    std::int64_t k = 0;
    for (auto _ : state) pose_head(head(), moving_pose(k++), posed);
    state.counters["frames_per_s"] = benchmark::Counter(double(k), benchmark::Counter::kIsRate);
    state.counters["load_1min"] = load_1min();
}
BENCHMARK(BM_Pose)->Unit(benchmark::kMillisecond);

void BM_Render(benchmark::State& state) {
    OffscreenRenderer renderer(head(), variant(state.range(0)));
    Image image;
    renderer.render(moving_pose(0), image);  // llvmpipe compiles its shaders at the first draw
    std::int64_t k = 0;
    for (auto _ : state) renderer.render(moving_pose(k++), image);
    state.SetLabel(variant_name(state.range(0)));
    state.counters["frames_per_s"] = benchmark::Counter(double(k), benchmark::Counter::kIsRate);
    state.counters["load_1min"] = load_1min();
}
BENCHMARK(BM_Render)->DenseRange(0, 4)->Unit(benchmark::kMillisecond)->UseRealTime();

// Render time against frame size: separates per-pixel from per-triangle cost.
void BM_RenderSize(benchmark::State& state) {
    RenderSettings rs;
    rs.width = static_cast<int>(state.range(0));
    rs.height = rs.width * 3 / 4;
    OffscreenRenderer renderer(head(), rs);
    Image image;
    renderer.render(moving_pose(0), image);
    std::int64_t k = 0;
    for (auto _ : state) renderer.render(moving_pose(k++), image);
    state.counters["frames_per_s"] = benchmark::Counter(double(k), benchmark::Counter::kIsRate);
    state.counters["load_1min"] = load_1min();
}
BENCHMARK(BM_RenderSize)->Arg(160)->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond)->UseRealTime();

// Colour conversion + H.264 encoding of rendered frames (no rendering).
void BM_Encode(benchmark::State& state) {
    OffscreenRenderer renderer(head());
    std::vector<Image> frames(30);
    for (std::size_t k = 0; k < frames.size(); ++k) renderer.render(moving_pose(std::int64_t(k)), frames[k]);
    const auto path = std::filesystem::temp_directory_path() / "avsi_bench_encode.mp4";
    std::int64_t n = 0;
    for (auto _ : state) {
        VideoWriter writer(path, 640, 480, 90, nullptr);
        for (int k = 0; k < 90; ++k) writer.write(frames[std::size_t(k) % frames.size()]);
        writer.finish();
        n += 90;
    }
    std::filesystem::remove(path);
    state.counters["frames_per_s"] = benchmark::Counter(double(n), benchmark::Counter::kIsRate);
    state.counters["load_1min"] = load_1min();
}
BENCHMARK(BM_Encode)->Unit(benchmark::kMillisecond)->UseRealTime();

// One 90-frame (3 s at 30 fps) stimulus with audio, rendered and encoded.
std::size_t render_one_stimulus(OffscreenRenderer& renderer, const std::filesystem::path& path) {
    avsi::synth::Trajectory traj;
    traj.fps = 30.0;
    for (int k = 0; k < 90; ++k) traj.frames.push_back(moving_pose(k).params);
    avsi::Audio audio;
    audio.sample_rate_hz = 16000;
    audio.samples.assign(48000, 0.0f);
    return render_video(renderer, traj, &audio, path);
}

void BM_RenderEncode(benchmark::State& state) {
    OffscreenRenderer renderer(head(), variant(state.range(0)));
    const auto path = std::filesystem::temp_directory_path() / "avsi_bench_stimuli.mp4";
    renderer.render(moving_pose(0));  // llvmpipe compiles its shaders at the first draw
    std::int64_t frames = 0;
    for (auto _ : state) frames += static_cast<std::int64_t>(render_one_stimulus(renderer, path));
    std::filesystem::remove(path);
    state.SetLabel(variant_name(state.range(0)));
    state.counters["frames_per_s"] = benchmark::Counter(double(frames), benchmark::Counter::kIsRate);
    state.counters["load_1min"] = load_1min();
}
BENCHMARK(BM_RenderEncode)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// Render + encode with one worker per core, as build-stimuli runs by default
// (--jobs 0: std::thread::hardware_concurrency() workers): each worker renders
// and encodes its own 90-frame stimuli with seeded blinks; frames/s is the
// total over the wall time. Also one worker, for the scaling.
void BM_RenderEncodeWorkers(benchmark::State& state) {
    const int workers = static_cast<int>(state.range(0));
    std::vector<std::unique_ptr<OffscreenRenderer>> renderers;
    for (int w = 0; w < workers; ++w) {
        renderers.push_back(std::make_unique<OffscreenRenderer>(head()));
        renderers.back()->render(moving_pose(0));
    }
    std::int64_t frames = 0;
    for (auto _ : state) {
        const auto start = std::chrono::steady_clock::now();
        std::vector<std::thread> threads;
        std::vector<std::size_t> made(static_cast<std::size_t>(workers), 0);
        for (int w = 0; w < workers; ++w)
            threads.emplace_back([&, w] {
                const auto path = std::filesystem::temp_directory_path() /
                                  ("avsi_bench_stimuli_w" + std::to_string(w) + ".mp4");
                for (int s = 0; s < 2; ++s) made[std::size_t(w)] += render_one_stimulus(*renderers[std::size_t(w)], path);
                std::filesystem::remove(path);
            });
        for (auto& t : threads) t.join();
        for (auto m : made) frames += static_cast<std::int64_t>(m);
        state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    state.counters["frames_per_s"] = benchmark::Counter(double(frames), benchmark::Counter::kIsRate);
    state.counters["load_1min"] = load_1min();
}
void worker_counts(benchmark::internal::Benchmark* b) {
    b->Arg(1);
    const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    if (cores > 1) b->Arg(cores);
}
BENCHMARK(BM_RenderEncodeWorkers)->Apply(worker_counts)->Unit(benchmark::kMillisecond)->UseManualTime();

}  // namespace

BENCHMARK_MAIN();
