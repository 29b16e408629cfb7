// Helpers for the ANN tests: models with seeded random or hand-set weights,
// and small synthetic training utterances.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "avsi/synth/ann.h"
#include "avsi/synth/articulatory_corpus.h"
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

// A synthetic utterance: jaw_rotation follows vowel openness, upper lip
// raise is low for bilabials, both smoothed (first-order lag) — a mapping a
// small recurrent network can learn. Only those two parameters are present;
// every 7th jaw value is missing (NaN).
inline CorpusUtterance synthetic_utterance(unsigned seed, int phones) {
    CorpusUtterance u;
    u.id = "syn" + std::to_string(seed);
    u.phones = random_phones(seed, phones);
    u.track.fps = 60.0;
    const std::size_t n = frame_count(u.phones.back().end_s, 60.0);
    const auto features = encode_frame_features(u.phones, 60.0, n);
    double jaw = 0.0, lip = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const auto& f = features[k];
        const double jaw_target = 0.1 + 0.6 * f[static_cast<std::size_t>(Feature::Open)];
        const double lip_target = f[static_cast<std::size_t>(Feature::Bilabial)] > 0.5 ? -0.2 : 0.2;
        jaw += 0.3 * (jaw_target - jaw);
        lip += 0.3 * (lip_target - lip);
        Frame fr{};
        for (auto& v : fr) v = std::nan("");
        fr[index(Param::JawRotation)] = k % 7 == 3 ? std::nan("") : jaw;
        fr[index(Param::UpperLipRaise)] = lip;
        u.track.frames.push_back(fr);
    }
    u.track.present[index(Param::JawRotation)] = true;
    u.track.present[index(Param::UpperLipRaise)] = true;
    return u;
}

}  // namespace avsi::synth::test
