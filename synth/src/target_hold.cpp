// Target hold (target_hold.h): the closure mechanism of the rule model.
#include "avsi/synth/target_hold.h"

#include <algorithm>
#include <cmath>

#include "avsi/core/error.h"

namespace avsi::synth {

namespace {

// The phone's base symbol (vowel stress digits are not part of the hold key).
std::string_view base_symbol(const Phone& phone) { return phone.symbol; }

}  // namespace

void hold_targets(const PhoneSequence& phones, std::span<const double> times_s, const RuleModel::Table& targets,
                  const TargetHoldSettings& settings, std::vector<Frame>& frames) {
    AVSI_ASSERT(frames.size() == times_s.size());
    if (settings.strength <= 0.0 || settings.phones.empty()) return;
    AVSI_ASSERT(settings.transition_s > 0.0);
    struct Held {
        double start_s, end_s;
        const RuleTarget* target;
    };
    std::vector<Held> held;
    for (const auto& ph : phones) {
        if (!settings.phones.count(base_symbol(ph))) continue;
        const auto it = targets.find(base_symbol(ph));
        if (it == targets.end()) continue;
        held.push_back({ph.start_s, ph.end_s, &it->second});
    }
    if (held.empty()) return;
    const double reach = 6.0 * settings.transition_s;  // h < 1.6e-8 beyond
    std::size_t first = 0;
    for (std::size_t k = 0; k < times_s.size(); ++k) {
        const double t = times_s[k];
        while (first < held.size() && held[first].end_s + reach < t) ++first;
        // Inside a held segment only the segments holding t count (its
        // target exactly); between segments, every nearby one's tail.
        bool inside = false;
        for (std::size_t i = first; i < held.size() && held[i].start_s <= t; ++i)
            inside = inside || t <= held[i].end_s;
        std::array<double, param_count> pull{}, weight{};
        for (std::size_t i = first; i < held.size() && held[i].start_s - reach <= t; ++i) {
            const double d = t < held[i].start_s ? held[i].start_s - t : t > held[i].end_s ? t - held[i].end_s : 0.0;
            if (d > reach || (inside && d > 0.0)) continue;
            const double h = d == 0.0 ? 1.0 : std::exp(-0.5 * (d / settings.transition_s) * (d / settings.transition_s));
            for (std::size_t p = 0; p < param_count; ++p) {
                const auto& target = (*held[i].target)[p];
                if (!target) continue;
                pull[p] += h * (*target - frames[k][p]);
                weight[p] += h;
            }
        }
        for (std::size_t p = 0; p < param_count; ++p)
            if (weight[p] > 0.0) frames[k][p] += settings.strength * pull[p] / std::max(1.0, weight[p]);
    }
}

std::filesystem::path default_hold_targets_path() {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "rule_targets.tsv";
}

}  // namespace avsi::synth
