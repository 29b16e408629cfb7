// Stimulus rendering speed: posing, rendering (OSMesa llvmpipe, 640×480,
// 4× MSAA), H.264 encoding, and render + encode together in frames/s.
// Run: build-stim/bench/bench_stimuli --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>

#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/stimuli/video.h"

namespace {

using namespace avsi::stimuli;

const Head& head() {
    static const Head h = load_default_head();
    return h;
}

Pose moving_pose(std::int64_t k) {
    Pose p;
    p.params[0] = 0.5 + 0.5 * std::sin(0.3 * double(k));
    p.params[1] = 0.5 * std::cos(0.2 * double(k));
    return p;
}

void BM_Pose(benchmark::State& state) {
    PosedMesh posed;
    std::int64_t k = 0;
    for (auto _ : state) pose_head(head(), moving_pose(k++), posed);
    state.counters["frames_per_s"] = benchmark::Counter(double(k), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Pose)->Unit(benchmark::kMillisecond);

void BM_Render(benchmark::State& state) {
    RenderSettings rs;
    rs.samples = static_cast<int>(state.range(0));
    OffscreenRenderer renderer(head(), rs);
    Image image;
    renderer.render(moving_pose(0), image);  // llvmpipe compiles its shaders at the first draw
    std::int64_t k = 0;
    for (auto _ : state) renderer.render(moving_pose(k++), image);
    state.counters["frames_per_s"] = benchmark::Counter(double(k), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Render)->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();

// Render time against frame size (samples = 4): separates per-pixel from per-triangle cost.
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
}
BENCHMARK(BM_RenderSize)->Arg(160)->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond)->UseRealTime();

// Render + encode a 90-frame (3 s at 30 fps) stimulus with audio.
void BM_RenderEncode(benchmark::State& state) {
    RenderSettings rs;
    rs.samples = static_cast<int>(state.range(0));
    OffscreenRenderer renderer(head(), rs);
    avsi::synth::Trajectory traj;
    traj.fps = 30.0;
    for (int k = 0; k < 90; ++k) traj.frames.push_back(moving_pose(k).params);
    avsi::Audio audio;
    audio.sample_rate_hz = 16000;
    audio.samples.assign(48000, 0.0f);
    const auto path = std::filesystem::temp_directory_path() / "avsi_bench_stimuli.mp4";
    renderer.render(moving_pose(0));  // llvmpipe compiles its shaders at the first draw
    std::int64_t frames = 0;
    for (auto _ : state) frames += static_cast<std::int64_t>(render_video(renderer, traj, &audio, path));
    std::filesystem::remove(path);
    state.counters["frames_per_s"] = benchmark::Counter(double(frames), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RenderEncode)->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
