// Helpers for the ANN tests: models with seeded random or hand-set weights
// and random phone sequences (training utterances: tests/learn/ann_corpus_util.h).
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "avsi/synth/ann.h"
#include "test_util.h"

namespace avsi::synth::test {

// The four Table-1 groups with `hidden` units each and weights uniform in ±scale.
inline AnnModel random_ann(const AnnConfig& config, int hidden, unsigned seed, float scale = 0.3f) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-scale, scale);
    std::vector<AnnNetwork> nets;
    for (AnnGroup g : ann_groups()) {
        g.hidden = hidden;
        AnnNetwork n;
        n.group = g;
        const auto h = static_cast<std::size_t>(hidden);
        auto fill = [&](std::vector<float>& v, std::size_t size) {
            v.resize(size);
            for (auto& x : v) x = u(rng);
        };
        fill(n.W, h * config.inputs());
        fill(n.U, h * h * static_cast<std::size_t>(config.delays));
        fill(n.b, h);
        fill(n.V, g.params.size() * h);
        fill(n.c, g.params.size());
        nets.push_back(std::move(n));
    }
    return AnnModel(config, std::move(nets));
}

inline const std::vector<std::string>& test_phone_symbols() {
    static const std::vector<std::string> s{"AA", "P", "IY", "M", "UW", "S", "F", "EH", "B", "OW"};
    return s;
}

// Random contiguous phones, 40–200 ms each, starting and ending with silence.
inline PhoneSequence random_phones(unsigned seed, int count) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<std::size_t> pick(0, test_phone_symbols().size() - 1);
    std::uniform_real_distribution<double> dur(0.04, 0.2);
    std::vector<std::pair<std::string, double>> items{{"sil", 0.1}};
    for (int i = 0; i < count; ++i) items.emplace_back(test_phone_symbols()[pick(rng)], dur(rng));
    items.emplace_back("sil", 0.1);
    return make_phones(items);
}

}  // namespace avsi::synth::test
