// The Cohen-Massaro model (Beskow §4.2, eq. 7–8): dominance functions, the
// full and the bounded (linear-time) weighted sums, and the model file.
// The bound is derived in cohen_massaro.h.
#include "avsi/synth/cohen_massaro.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "model_json.h"

namespace avsi::synth {

namespace {

// A segment prepared for evaluation: ln α instead of α.
struct Seg {
    double tau;
    double target;
    double log_alpha;
    double theta;
    double phi;
    double c;
};

// rate · d^c for d >= 0, with the common exponents exact and fast.
inline double decay(double d, double rate, double c) {
    if (c == 1.0) return rate * d;
    if (c == 2.0) return rate * d * d;
    return rate * std::pow(d, c);
}

inline double log_dom(const Seg& s, double t) {
    const double d = s.tau - t;
    return d > 0.0 ? s.log_alpha - decay(d, s.theta, s.c) : s.log_alpha - decay(-d, s.phi, s.c);
}

// The r >= 0 with rate · r^c = x (x >= 0).
inline double reach(double x, double rate, double c) {
    const double y = x / rate;
    return c == 1.0 ? y : c == 2.0 ? std::sqrt(y) : std::pow(y, 1.0 / c);
}

Seg prepare(const CmSegment& s) {
    AVSI_ASSERT(s.alpha > 0.0 && s.theta_per_s > 0.0 && s.phi_per_s > 0.0 && s.c > 0.0);
    return {s.tau_s, s.target, std::log(s.alpha), s.theta_per_s, s.phi_per_s, s.c};
}

}  // namespace

double log_dominance(const CmSegment& segment, double t_s) { return log_dom(prepare(segment), t_s); }

double dominance(const CmSegment& segment, double t_s) { return std::exp(log_dominance(segment, t_s)); }

void cohen_massaro_full(std::span<const CmSegment> segments, std::span<const double> times_s,
                        std::span<double> out) {
    AVSI_ASSERT(!segments.empty() && out.size() == times_s.size());
    std::vector<Seg> segs;
    segs.reserve(segments.size());
    for (const auto& s : segments) segs.push_back(prepare(s));
    std::vector<double> logs(segs.size());
    for (std::size_t k = 0; k < times_s.size(); ++k) {
        const double t = times_s[k];
        double top = -std::numeric_limits<double>::infinity();
        for (std::size_t i = 0; i < segs.size(); ++i) {
            logs[i] = log_dom(segs[i], t);
            top = std::max(top, logs[i]);
        }
        double num = 0.0, den = 0.0;
        for (std::size_t i = 0; i < segs.size(); ++i) {
            const double w = std::exp(logs[i] - top);
            num += segs[i].target * w;
            den += w;
        }
        out[k] = num / den;
    }
}

void cohen_massaro_bounded(std::span<const CmSegment> segments, std::span<const double> times_s,
                           std::span<double> out, double tolerance) {
    AVSI_ASSERT(!segments.empty() && out.size() == times_s.size());
    AVSI_ASSERT(std::is_sorted(times_s.begin(), times_s.end()));
    if (!(tolerance > 0.0)) {
        cohen_massaro_full(segments, times_s, out);
        return;
    }
    // Step 1: segments sorted by centre; global extremes for the reach bound.
    std::vector<Seg> segs;
    segs.reserve(segments.size());
    for (const auto& s : segments) segs.push_back(prepare(s));
    std::stable_sort(segs.begin(), segs.end(), [](const Seg& a, const Seg& b) { return a.tau < b.tau; });
    const std::size_t n = segs.size();
    double t_min = segs[0].target, t_max = segs[0].target;
    double max_log_alpha = segs[0].log_alpha, min_rate = std::min(segs[0].theta, segs[0].phi);
    double c_min = segs[0].c, c_max = segs[0].c;
    for (const auto& s : segs) {
        t_min = std::min(t_min, s.target);
        t_max = std::max(t_max, s.target);
        max_log_alpha = std::max(max_log_alpha, s.log_alpha);
        min_rate = std::min({min_rate, s.theta, s.phi});
        c_min = std::min(c_min, s.c);
        c_max = std::max(c_max, s.c);
    }
    const double spread = t_max - t_min;
    if (spread == 0.0) {
        std::fill(out.begin(), out.end(), t_min);
        return;
    }
    // δ_j = ε·L_j/(ΔT·N): ln δ_j = ln L_j + ln_factor (never above ln L_j).
    const double ln_factor = std::min(0.0, std::log(tolerance / (spread * static_cast<double>(n))));
    // The largest reach of any segment down to ln δ: x^(1/c) is monotone in
    // c for fixed x, so the extremes of c bound it.
    auto reach_bound = [&](double ln_delta) {
        const double x = (max_log_alpha - ln_delta) / min_rate;
        if (x <= 0.0) return 0.0;
        return std::max(std::pow(x, 1.0 / c_min), std::pow(x, 1.0 / c_max));
    };
    std::vector<double> taus(n);
    for (std::size_t i = 0; i < n; ++i) taus[i] = segs[i].tau;

    std::vector<std::size_t> candidates;
    std::vector<double> logs, num, den;
    std::size_t k = 0;
    const std::size_t frames = times_s.size();
    // Uniformly spaced times allow the c = 1 recurrence (see step 5).
    bool uniform = frames >= 2;
    const double step = uniform ? (times_s[frames - 1] - times_s[0]) / static_cast<double>(frames - 1) : 0.0;
    for (std::size_t f = 0; uniform && f < frames; ++f)
        uniform = std::abs(times_s[f] - (times_s[0] + step * static_cast<double>(f))) <= 1e-12 * (1.0 + std::abs(times_s[f]));
    std::vector<double> rise_factor(n), fall_factor(n), last_weight(n, 0.0);
    std::vector<std::size_t> last_frame(n, static_cast<std::size_t>(-2));
    if (uniform)
        for (std::size_t i = 0; i < n; ++i) {
            rise_factor[i] = std::exp(segs[i].theta * step);
            fall_factor[i] = std::exp(-segs[i].phi * step);
        }
    for (std::size_t j = 0; j < n && k < frames; ++j) {
        // Step 2: the frames of cell j (nearer τ_j than the next centre).
        const double upper = j + 1 < n ? 0.5 * (taus[j] + taus[j + 1]) : std::numeric_limits<double>::infinity();
        const std::size_t k0 = k;
        while (k < frames && times_s[k] < upper) ++k;
        if (k == k0) continue;
        const double ta = times_s[k0], tb = times_s[k - 1];
        // Step 3: L_j, the owner's smallest dominance over the cell's frames
        // (D_j is unimodal, so at an end), and the threshold δ_j.
        const double ln_l = std::min(log_dom(segs[j], ta), log_dom(segs[j], tb));
        const double ln_delta = ln_l + ln_factor;
        // Step 4: candidates: segments whose dominance reaches δ_j somewhere in [ta, tb].
        const double r = reach_bound(ln_delta);
        const auto lo = static_cast<std::size_t>(std::lower_bound(taus.begin(), taus.end(), ta - r) - taus.begin());
        const auto hi = static_cast<std::size_t>(std::upper_bound(taus.begin(), taus.end(), tb + r) - taus.begin());
        candidates.clear();
        for (std::size_t i = lo; i < hi; ++i) {
            const Seg& s = segs[i];
            const double x = s.log_alpha - ln_delta;
            if (x < 0.0) continue;
            if (s.tau - reach(x, s.theta, s.c) > tb || s.tau + reach(x, s.phi, s.c) < ta) continue;
            candidates.push_back(i);
        }
        // Step 5: the weighted mean over the candidates.
        if (uniform && ln_delta > -680.0) {
            // Absolute dominances (every kept one is >= δ_j > e^−680, none
            // overflows), for c = 1 by the recurrence D(t + h) = D(t)·e^{±rate·h}
            // along the frames, continued from the previous cell.
            num.assign(k - k0, 0.0);
            den.assign(k - k0, 0.0);
            for (std::size_t i : candidates) {
                const Seg& sg = segs[i];
                if (sg.c != 1.0) {
                    for (std::size_t f = k0; f < k; ++f) {
                        const double w = std::exp(log_dom(sg, times_s[f]));
                        num[f - k0] += sg.target * w;
                        den[f - k0] += w;
                    }
                    continue;
                }
                const double rise = rise_factor[i], fall = fall_factor[i];
                double w;
                if (last_frame[i] + 1 == k0 && k0 > 0 && (times_s[k0 - 1] < sg.tau) == (times_s[k0] < sg.tau))
                    w = last_weight[i] * (times_s[k0] < sg.tau ? rise : fall);
                else
                    w = std::exp(log_dom(sg, times_s[k0]));
                num[0] += sg.target * w;
                den[0] += w;
                for (std::size_t f = k0 + 1; f < k; ++f) {
                    const bool before = times_s[f] < sg.tau;
                    if (before == (times_s[f - 1] < sg.tau))
                        w *= before ? rise : fall;
                    else
                        w = std::exp(log_dom(sg, times_s[f]));  // crossed the peak
                    num[f - k0] += sg.target * w;
                    den[f - k0] += w;
                }
                last_frame[i] = k - 1;
                last_weight[i] = w;
            }
            for (std::size_t f = k0; f < k; ++f) out[f] = num[f - k0] / den[f - k0];
            continue;
        }
        // General times or extreme dominance ranges: per frame in the log
        // domain, shifted by the largest dominance.
        logs.resize(candidates.size());
        for (std::size_t f = k0; f < k; ++f) {
            const double t = times_s[f];
            double top = -std::numeric_limits<double>::infinity();
            for (std::size_t q = 0; q < candidates.size(); ++q) {
                logs[q] = log_dom(segs[candidates[q]], t);
                top = std::max(top, logs[q]);
            }
            double num_f = 0.0, den_f = 0.0;
            for (std::size_t q = 0; q < candidates.size(); ++q) {
                if (logs[q] < ln_delta) continue;
                const double w = std::exp(logs[q] - top);
                num_f += segs[candidates[q]].target * w;
                den_f += w;
            }
            out[f] = num_f / den_f;
        }
    }
}

std::vector<CmSegment> DominanceModel::segments(const PhoneSequence& phones, Param param) const {
    return std::move(segments_all(phones)[index(param)]);
}

void DominanceModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                              std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    const auto all = segments_all(phones);
    out.assign(times_s.size(), Frame{});
    std::vector<double> values(times_s.size());
    for (std::size_t p = 0; p < param_count; ++p) {
        cohen_massaro_bounded(all[p], times_s, values, tolerance);
        for (std::size_t k = 0; k < values.size(); ++k) out[k][p] = values[k];
    }
}

std::array<std::vector<CmSegment>, param_count> CohenMassaroModel::segments_all(const PhoneSequence& phones) const {
    std::array<std::vector<CmSegment>, param_count> out;
    for (auto& v : out) v.reserve(phones.size());
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const CohenMassaroPhone* entry = find_phone_entry(m_phones, phones[i]);
        if (!entry) detail::missing_phone(phones[i], i, kind());
        const double tau = phones[i].centre_s();
        for (std::size_t p = 0; p < param_count; ++p) {
            const CohenMassaroParams& q = entry->params[p];
            out[p].push_back({tau, q.target, q.alpha, q.theta_per_s, q.phi_per_s, entry->c});
        }
    }
    return out;
}

std::string CohenMassaroModel::to_json_text() const {
    using detail::json;
    json j = detail::model_header(*this);
    json phones = json::object();
    for (const auto& [key, entry] : m_phones) {
        json ps = json::object();
        for (const auto& info : params()) {
            const CohenMassaroParams& q = entry.params[index(info.param)];
            ps[std::string(info.name)] =
                json{{"target", q.target}, {"alpha", q.alpha}, {"theta", q.theta_per_s}, {"phi", q.phi_per_s}};
        }
        phones[key] = json{{"c", entry.c}, {"params", ps}};
    }
    j["phones"] = phones;
    return j.dump(2) + "\n";
}

namespace detail {

std::unique_ptr<ControlModel> load_cohen_massaro(const json& root, const std::filesystem::path&, JsonReader& reader) {
    reader.check_keys(root, {"kind", "version", "provenance", "phones", "tolerance"}, "");
    CohenMassaroModel::Table table;
    if (const json* phones = reader.require(root, "phones", "/phones")) {
        if (!phones->is_object() || phones->empty())
            reader.error("/phones", "expected an object with one entry per phone");
        else
            for (const auto& [key, node] : phones->items()) {
                const std::string base = "/phones/" + pointer_token(key);
                if (!reader.phone_key(key, base)) continue;
                if (!node.is_object()) {
                    reader.error(base, fmt::format("expected an object, got {}", node.dump()));
                    continue;
                }
                reader.check_keys(node, {"c", "params"}, base);
                CohenMassaroPhone entry;
                if (auto c = reader.number_field(node, "c", base + "/c", 0.0, 10.0, true)) entry.c = *c;
                const json* ps = reader.require(node, "params", base + "/params");
                if (!ps) continue;
                std::vector<std::string> names;
                for (const auto& info : params()) names.emplace_back(info.name);
                reader.check_keys(*ps, names, base + "/params", "parameter");
                for (const auto& info : params()) {
                    const std::string pp = base + "/params/" + std::string(info.name);
                    const json* q = reader.require(*ps, std::string(info.name), pp);
                    if (!q) continue;
                    reader.check_keys(*q, {"target", "alpha", "theta", "phi"}, pp);
                    CohenMassaroParams& out = entry.params[index(info.param)];
                    if (const json* t = reader.require(*q, "target", pp + "/target"))
                        if (auto v = reader.param_value(*t, info.param, pp + "/target")) out.target = *v;
                    if (auto v = reader.number_field(*q, "alpha", pp + "/alpha", 0.0, 1e6, true)) out.alpha = *v;
                    if (auto v = reader.number_field(*q, "theta", pp + "/theta", 0.0, 1e6, true)) out.theta_per_s = *v;
                    if (auto v = reader.number_field(*q, "phi", pp + "/phi", 0.0, 1e6, true)) out.phi_per_s = *v;
                }
                table[key] = entry;
            }
    }
    auto model = std::make_unique<CohenMassaroModel>(std::move(table));
    if (root.contains("tolerance"))
        if (auto v = reader.number(root["tolerance"], "/tolerance", 0.0, 1e-3)) model->tolerance = *v;
    return model;
}

}  // namespace detail
}  // namespace avsi::synth
