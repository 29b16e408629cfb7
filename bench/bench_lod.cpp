// Level of detail (stimuli/lod.h): the built-in head at full detail and
// levels 1-3 — triangle count, render time per frame (OSMesa llvmpipe) at
// the stimulus resolution 640×480 and at 320×240, with the default static-
// part cache and without it (every triangle drawn each frame), and the
// difference from full detail over every frame of a running-speech sentence
// (the first of tests/data/articulation/sentences.txt, timed by espeak-ng,
// through the rule model at 30 fps): mean absolute RGB difference (of 255),
// PSNR over all its frames (dB), and the largest difference of any
// articulation measure (mm).
// Run with the rasteriser on the calling thread, so the CPU column is the
// whole frame's CPU time (the machine may be shared; wall time is not):
//   LP_NUM_THREADS=0 build/bench/bench_lod --benchmark_counters_tabular=true
// Each result carries the 1-minute load average at its end (load_1min).
#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "avsi/core/text.h"
#include "avsi/core/tts.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/lod.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/synth/control_model.h"

namespace {

using namespace avsi::stimuli;

double load_1min() {
    double load[1] = {0.0};
    return getloadavg(load, 1) == 1 ? load[0] : -1.0;
}

const Head& head() {
    static const Head h = load_default_head();
    return h;
}

const avsi::synth::Trajectory& sentence() {
    static const avsi::synth::Trajectory t = [] {
        std::ifstream in(std::filesystem::path(AVSI_TEST_DATA_DIR) / "articulation" / "sentences.txt");
        std::string text;
        for (std::string line; std::getline(in, line);)
            if (!avsi::trim(line).empty() && line[0] != '#') {
                text = avsi::trim(line);
                break;
            }
        const auto phones = avsi::synthesize_speech(text).phones;
        return avsi::synth::load_model(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json")
            ->synthesize(phones, 30.0);
    }();
    return t;
}

std::vector<Pose> poses() {
    std::vector<Pose> out;
    for (const auto& f : sentence().frames) {
        Pose p;
        p.params = f;
        out.push_back(p);
    }
    return out;
}

RenderSettings settings(int level, int width, bool cache) {
    RenderSettings rs;
    rs.width = width;
    rs.height = width * 3 / 4;
    rs.cache_static = cache;
    rs.lod.level = level;
    return rs;
}

// Every frame of the sentence at full detail, per frame size.
const std::vector<Image>& reference(int width) {
    static std::map<int, std::vector<Image>> cache;
    auto& frames = cache[width];
    if (frames.empty()) {
        OffscreenRenderer renderer(head(), settings(0, width, true));
        for (const auto& p : poses()) frames.push_back(renderer.render(p));
    }
    return frames;
}

double articulation_difference_mm(const Head& lod_head) {
    const auto a = ArticulationMeter(head()).measure(sentence());
    const auto b = ArticulationMeter(lod_head).measure(sentence());
    double worst = 0.0;
    for (std::size_t f = 0; f < a.size(); ++f)
        for (const auto d :
             {a[f].aperture_mid_mm - b[f].aperture_mid_mm, a[f].aperture_min_mm - b[f].aperture_min_mm,
              a[f].aperture_max_mm - b[f].aperture_max_mm, a[f].aperture_all_min_mm - b[f].aperture_all_min_mm,
              a[f].mouth_width_mm - b[f].mouth_width_mm, a[f].upper_protrusion_mm - b[f].upper_protrusion_mm,
              a[f].lower_protrusion_mm - b[f].lower_protrusion_mm, a[f].jaw_opening_mm - b[f].jaw_opening_mm,
              a[f].lip_to_incisors_mm - b[f].lip_to_incisors_mm})
            worst = std::max(worst, std::abs(d));
    return worst;
}

// range(0): level 0-3; range(1): frame width (640 or 320, 4:3); range(2): 1 = static-part cache (default).
void BM_RenderLod(benchmark::State& state) {
    const int level = int(state.range(0));
    const int width = int(state.range(1));
    const bool cache = state.range(2) != 0;
    OffscreenRenderer renderer(head(), settings(level, width, cache));
    const auto ps = poses();
    // The difference from full detail over every frame of the sentence.
    const auto& ref = reference(width);
    double abs_sum = 0.0, sq_sum = 0.0, n = 0.0;
    Image img;
    for (std::size_t i = 0; i < ps.size(); ++i) {
        renderer.render(ps[i], img);
        for (std::size_t k = 0; k < img.rgb.size(); ++k) {
            const double d = double(img.rgb[k]) - double(ref[i].rgb[k]);
            abs_sum += std::abs(d);
            sq_sum += d * d;
        }
        n += double(img.rgb.size());
    }
    std::size_t k = 0;
    for (auto _ : state) {
        renderer.render(ps[k % ps.size()], img);
        benchmark::DoNotOptimize(img.rgb.data());
        ++k;
    }
    const double mse = sq_sum / n;
    state.counters["triangles"] = double(renderer.head().mesh.triangle_count());
    state.counters["mean_abs_rgb"] = abs_sum / n;
    state.counters["psnr_db"] = mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
    state.counters["artic_max_mm"] = articulation_difference_mm(renderer.head());
    state.counters["error_mm"] = renderer.lod() ? renderer.lod()->error_mm : 0.0;
    state.counters["load_1min"] = load_1min();
    state.SetLabel(fmt::format("level {} {}x{}{}", level, width, width * 3 / 4, cache ? "" : " no cache"));
}
BENCHMARK(BM_RenderLod)
    ->ArgsProduct({{0, 1, 2, 3}, {640, 320}, {1}})
    ->ArgsProduct({{0, 1, 2, 3}, {640}, {0}})
    ->Unit(benchmark::kMillisecond);

// Making a level: the simplification itself (meshoptimizer and re-indexing).
void BM_SimplifyLevel(benchmark::State& state) {
    const int level = int(state.range(0));
    std::size_t triangles = 0;
    for (auto _ : state) triangles = head_at_level(head(), level).triangles;
    state.counters["triangles"] = double(triangles);
    state.counters["load_1min"] = load_1min();
}
BENCHMARK(BM_SimplifyLevel)->DenseRange(1, 3)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
