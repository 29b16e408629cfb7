// Benchmarks of the analysis module: the repeated-measures ANOVA with
// sphericity for a study-sized data set, reading the scoring lexicon, keyword
// scoring of one response under each rule set, and one simulated experiment
// of the power analysis.
#include <benchmark/benchmark.h>

#include "avsi/analysis/lexicon.h"
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

// The SCOWL word lists (wamerican + wbritish) read from disk, as the first
// lenient scorer of a process does (later ones share it).
void BM_LexiconLoad(benchmark::State& state) {
    for (auto _ : state) benchmark::DoNotOptimize(Lexicon::read(Lexicon::default_files()));
}
BENCHMARK(BM_LexiconLoad)->Unit(benchmark::kMillisecond);

void BM_LexiconLookup(benchmark::State& state) {
    const auto lexicon = Lexicon::shared();
    const char* words[] = {"pound", "gardne", "windows", "brekfast", "evening", "kitchne"};
    std::size_t i = 0;
    for (auto _ : state) benchmark::DoNotOptimize(lexicon->contains(words[i++ % 6]));
}
BENCHMARK(BM_LexiconLookup);

// One typed answer under a rule set (0 strict, 1 loose, 2 lenient).
void BM_ScoreResponse(benchmark::State& state) {
    ScoringSettings settings;
    settings.rules = kRuleSets[std::size_t(state.range(0))];
    const KeywordScorer scorer(settings);
    avsi::Sentence s;
    s.id = "s1";
    s.text = "The dog barked at the mailman.";
    s.keywords = {{"dog", {"dogs"}}, {"barked", {}}, {"mailman", {"postman"}}};
    for (auto _ : state) benchmark::DoNotOptimize(scorer.score(s, "the dogs were barkng at the mailmen"));
}
BENCHMARK(BM_ScoreResponse)->Arg(0)->Arg(1)->Arg(2);

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
