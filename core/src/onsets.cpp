// Acoustic onsets of stops and fricatives after vowels (see onsets.h).
#include "avsi/core/onsets.h"

#include <algorithm>
#include <cmath>

#include "avsi/core/error.h"

namespace avsi {

std::vector<ObstruentOnset> obstruent_onsets(const Audio& audio, const PhoneSequence& phones,
                                             const OnsetSettings& settings) {
    AVSI_ASSERT(audio.channels == 1 && audio.sample_rate_hz > 0);
    AVSI_ASSERT(settings.window_s > 0.0 && settings.step_s > 0.0);
    const PhoneInventory& inventory = PhoneInventory::builtin();
    const double rate = audio.sample_rate_hz;
    const long n = static_cast<long>(audio.samples.size());
    // Prefix sums of squared samples: the mean energy of any span in O(1).
    std::vector<double> cumulative(audio.samples.size() + 1, 0.0);
    for (std::size_t i = 0; i < audio.samples.size(); ++i)
        cumulative[i + 1] = cumulative[i] + double(audio.samples[i]) * double(audio.samples[i]);
    const auto level_db = [&](double from_s, double to_s) {
        const long a = std::clamp(std::lround(from_s * rate), 0L, n);
        const long b = std::clamp(std::lround(to_s * rate), 0L, n);
        const double mean = b > a ? (cumulative[static_cast<std::size_t>(b)] - cumulative[static_cast<std::size_t>(a)]) / double(b - a) : 0.0;
        return 10.0 * std::log10(mean + 1e-12);
    };

    std::vector<ObstruentOnset> out;
    for (std::size_t i = 1; i < phones.size(); ++i) {
        const Phone& p = phones[i];
        const Phone& q = phones[i - 1];
        if (p.symbol == "sil" || !inventory.is_vowel(q.symbol)) continue;
        const FeatureVector f = inventory.features_of(p);
        const bool stop = f[static_cast<std::size_t>(Feature::Stop)] == 1.0f;
        const bool fricative = f[static_cast<std::size_t>(Feature::Fricative)] == 1.0f;
        if (!stop && !fricative) continue;
        ObstruentOnset o;
        o.phone = i;
        o.symbol = p.symbol;
        o.previous = q.symbol;
        o.stop = stop;
        o.label_s = p.start_s;
        o.acoustic_s = p.start_s;
        o.drop_db = -1e300;
        const int steps = static_cast<int>(std::floor((p.centre_s() - q.centre_s()) / settings.step_s));
        for (int k = 0; k <= steps; ++k) {
            const double t = q.centre_s() + k * settings.step_s;
            const double drop = level_db(t - settings.window_s, t) - level_db(t, t + settings.window_s);
            if (drop > o.drop_db) {
                o.drop_db = drop;
                o.acoustic_s = t;
            }
        }
        out.push_back(o);
    }
    return out;
}

std::size_t align_obstruent_onsets(const Audio& audio, PhoneSequence& phones, const OnsetAlignment& alignment) {
    AVSI_ASSERT(alignment.max_shift_s >= 0.0);
    std::size_t moved = 0;
    for (const ObstruentOnset& o : obstruent_onsets(audio, phones)) {
        if (o.drop_db < alignment.min_drop_db || std::abs(o.offset_s()) > alignment.max_shift_s) continue;
        if (o.acoustic_s == o.label_s) continue;
        phones[o.phone - 1].end_s = o.acoustic_s;
        phones[o.phone].start_s = o.acoustic_s;
        ++moved;
    }
    return moved;
}

}  // namespace avsi
