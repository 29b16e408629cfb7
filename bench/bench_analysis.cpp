// Benchmarks of the analysis module: the repeated-measures ANOVA with
// sphericity for a study-sized data set, keyword scoring of one response,
// and one simulated experiment of the power analysis.
#include <benchmark/benchmark.h>

#include "avsi/analysis/power.h"
#include "avsi/analysis/rm_anova.h"
#include "avsi/analysis/scoring.h"
#include "avsi/core/rng.h"

namespace {

using namespace avsi::analysis;

void BM_RmAnova25x6(benchmark::State& state) {
    avsi::Rng rng(1);
    std::vector<double> values(25 * 6);
    for (auto& v : values) v = rng.uniform(20.0, 80.0);
    const auto data = make_within_data(std::vector<std::string>(25), std::vector<std::string>(6), values);
    for (auto _ : state) benchmark::DoNotOptimize(rm_anova(data));
}
BENCHMARK(BM_RmAnova25x6);

void BM_ScoreResponse(benchmark::State& state) {
    KeywordScorer scorer;
    avsi::Sentence s;
    s.id = "s1";
    s.text = "The dog barked at the mailman.";
    s.keywords = {{"dog", {"dogs"}}, {"barked", {}}, {"mailman", {"postman"}}};
    for (auto _ : state) benchmark::DoNotOptimize(scorer.score(s, "the dogs were barking at the mailmen"));
}
BENCHMARK(BM_ScoreResponse);

void BM_PowerOneSubjectCount(benchmark::State& state) {
    PowerSettings s;
    s.means_percent = {40, 48, 52, 55, 58, 62};
    s.subject_counts = {25};
    s.simulations = 100;
    s.threads = 1;
    for (auto _ : state) benchmark::DoNotOptimize(simulate_power(s));
}
BENCHMARK(BM_PowerOneSubjectCount)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
