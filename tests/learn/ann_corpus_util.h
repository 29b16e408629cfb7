// Small synthetic training utterances for the ANN training tests (the
// models and phones come from synth's ann_test_util.h).
#pragma once

#include <cmath>
#include <string>

#include "ann_test_util.h"
#include "avsi/learn/articulatory_corpus.h"

namespace avsi::synth::test {

// A synthetic utterance: jaw_rotation follows vowel openness, upper lip
// raise is low for bilabials, both smoothed (first-order lag) — a mapping a
// small recurrent network can learn. Only those two parameters are present;
// every 7th jaw value is missing (NaN).
inline learn::CorpusUtterance synthetic_utterance(unsigned seed, int phones) {
    learn::CorpusUtterance u;
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
