// The Cohen-Massaro model (Beskow §4.2): the dominance function (eq. 7),
// the pointwise weighted sum z(t) (eq. 8, CmPointwiseSum: the full sum, and
// what training differentiates), the bounded linear-time sum over its named
// steps (cm_bounded_sum.h; the bound is derived in cohen_massaro.h), and
// the model file.
#include "avsi/synth/cohen_massaro.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "cm_bounded_sum.h"
#include "cm_kernel.h"
#include "model_json.h"

namespace avsi::synth {

namespace {

// Segment i's term at t with ln D_i(t) (eq. 7) in `weight`: x = |τ_i − t|,
// x^c as exp(c·ln x) (exactly x for c = 1, when ln x is computed only if
// asked for).
inline CmTerm segment_term(const CmSegment& s, double log_alpha, std::uint32_t i, double t, bool need_log_x) {
    CmTerm term{i, t < s.tau_s, std::abs(s.tau_s - t), 0.0, 0.0, 0.0};
    if (term.distance_s > 0 && (need_log_x || s.c != 1.0)) term.log_distance = std::log(term.distance_s);
    term.distance_c = s.c == 1.0 ? term.distance_s : (term.distance_s > 0 ? std::exp(s.c * term.log_distance) : 0.0);
    term.weight = log_alpha - (term.before ? s.theta_per_s : s.phi_per_s) * term.distance_c;
    return term;
}

void check_segment(const CmSegment& s) {
    AVSI_ASSERT(s.alpha > 0.0 && s.theta_per_s > 0.0 && s.phi_per_s > 0.0 && s.c > 0.0);
}

// The bounded sum of eq. 8 (derivation in cohen_massaro.h) for P parameters
// whose segments share centre and exponent: source(p, i) is parameter p's
// segment i (any order); sink(frame, p, z) receives each value. The named
// steps are in cm_bounded_sum.h.
template <int P, class Source, class Sink>
void bounded_sum(std::size_t n, const Source& source, std::span<const double> times, double tolerance,
                 const Sink& sink) {
    using namespace detail;
    // The working storage, kept per thread between calls: no fresh pages for
    // every utterance.
    struct Workspace {
        CmTable<P> table;
        CmCutOffs<P> cut;
        CmFrameSums<P> rec_num, rec_den;  // the c = 1 segments' sums per frame
        CmBlockScratch<P> scratch;
    };
    static thread_local Workspace w;
    cm_table<P>(n, source, tolerance, w.table);
    const std::optional<double> step = uniform_step(times);
    const std::vector<char> recursive = cm_recursive_segments(w.table, times, step.has_value());
    cm_cut_offs(w.table, times, recursive, w.cut);
    const bool any_recursive = std::any_of(recursive.begin(), recursive.end(), [](char r) { return r != 0; });
    if (any_recursive) {
        w.rec_num.assign(times.size(), {});
        w.rec_den.assign(times.size(), {});
        recursive_sums<P>(times, *step, w.table.tau, recursive, w.table.theta, w.table.phi, w.table.alpha,
                          w.table.target_alpha, w.rec_num, w.rec_den);
    }
    cm_accumulate_blocks(w.table, times, step, w.cut, any_recursive ? &w.rec_num : nullptr,
                         any_recursive ? &w.rec_den : nullptr, w.scratch, sink);
    cm_log_domain_cells(w.table, times, w.cut.log_cells, sink);
}

}  // namespace

double log_dominance(const CmSegment& segment, double t_s) {
    check_segment(segment);
    return segment_term(segment, std::log(segment.alpha), 0, t_s, false).weight;
}

double dominance(const CmSegment& segment, double t_s) { return std::exp(log_dominance(segment, t_s)); }

CmPointwiseSum::CmPointwiseSum(std::span<const CmSegment> s, double skip_log_ratio)
    : m_s(s),
      m_skip_log_ratio(skip_log_ratio),
      m_log_alpha(s.size()),
      m_max_log_alpha(-std::numeric_limits<double>::infinity()),
      m_min_theta(std::numeric_limits<double>::infinity()),
      m_min_phi(std::numeric_limits<double>::infinity()),
      m_min_c(std::numeric_limits<double>::infinity()) {
    AVSI_ASSERT(!s.empty());
    for (std::size_t i = 0; i < s.size(); ++i) {
        check_segment(s[i]);
        AVSI_ASSERT(i == 0 || s[i].tau_s >= s[i - 1].tau_s);
        m_log_alpha[i] = std::log(s[i].alpha);
        m_max_log_alpha = std::max(m_max_log_alpha, m_log_alpha[i]);
        m_min_theta = std::min(m_min_theta, s[i].theta_per_s);
        m_min_phi = std::min(m_min_phi, s[i].phi_per_s);
        m_min_c = std::min(m_min_c, s[i].c);
        m_max_c = std::max(m_max_c, s[i].c);
    }
}

double CmPointwiseSum::collect(double t, bool need_log_x) {
    m_terms.clear();
    const std::size_t n = m_s.size();
    const auto first_after = static_cast<std::size_t>(
        std::lower_bound(m_s.begin(), m_s.end(), t, [](const CmSegment& s, double v) { return s.tau_s < v; }) -
        m_s.begin());
    double m = -std::numeric_limits<double>::infinity();
    // (Inlined: this is training's innermost loop.)
    auto add = [&](std::size_t i) __attribute__((always_inline)) {
        const CmTerm term = segment_term(m_s[i], m_log_alpha[i], static_cast<std::uint32_t>(i), t, need_log_x);
        m = std::max(m, term.weight);
        m_terms.push_back(term);
    };
    if (first_after > 0) add(first_after - 1);
    if (first_after < n) add(first_after);
    // Anticipatory side (later centres, θ), then carry-over side (earlier, φ).
    double reach_m = m, reach = max_distance(m, m_min_theta);
    for (std::size_t i = first_after + 1; i < n; ++i) {
        if (m != reach_m) reach = max_distance(reach_m = m, m_min_theta);
        if (m_s[i].tau_s - t > reach) break;
        add(i);
    }
    reach_m = m;
    reach = max_distance(m, m_min_phi);
    for (std::size_t i = first_after >= 1 ? first_after - 1 : 0; i-- > 0;) {
        if (m != reach_m) reach = max_distance(reach_m = m, m_min_phi);
        if (t - m_s[i].tau_s > reach) break;
        add(i);
    }
    return m;
}

double CmPointwiseSum::max_distance(double m, double rate) const {
    const double y = (m_max_log_alpha - m + m_skip_log_ratio) / rate;
    if (y <= 0) return 0.0;
    const double c = y < 1.0 ? m_max_c : m_min_c;
    return c == 1.0 ? y : std::pow(y, 1.0 / c);
}

double CmPointwiseSum::evaluate(double t_s, bool need_log_distance) {
    const double m = collect(t_s, need_log_distance);
    // ln D_i − max ln D, then D_i / max D (vectorised), and eq. 8.
    m_ratio.resize(m_terms.size());
    for (std::size_t e = 0; e < m_terms.size(); ++e) m_ratio[e] = m_terms[e].weight - m;
    detail::cm_exp(m_ratio.data(), m_ratio.size());
    double sum = 0.0, num = 0.0;
    for (std::size_t e = 0; e < m_terms.size(); ++e) {
        CmTerm& term = m_terms[e];
        term.weight = m_ratio[e];
        sum += term.weight;
        num += term.weight * m_s[term.segment].target;
    }
    m_weight_sum = sum;
    return num / sum;
}

void cohen_massaro_full(std::span<const CmSegment> segments, std::span<const double> times_s,
                        std::span<double> out) {
    AVSI_ASSERT(!segments.empty() && out.size() == times_s.size());
    const auto by_centre = [](const CmSegment& a, const CmSegment& b) { return a.tau_s < b.tau_s; };
    std::vector<CmSegment> sorted;
    if (!std::is_sorted(segments.begin(), segments.end(), by_centre)) {
        sorted.assign(segments.begin(), segments.end());
        std::stable_sort(sorted.begin(), sorted.end(), by_centre);
        segments = sorted;
    }
    CmPointwiseSum sum(segments, std::numeric_limits<double>::infinity());
    for (std::size_t k = 0; k < times_s.size(); ++k) out[k] = sum.evaluate(times_s[k]);
}

void cohen_massaro_bounded(std::span<const CmSegment> segments, std::span<const double> times_s,
                           std::span<double> out, double tolerance) {
    AVSI_ASSERT(!segments.empty() && out.size() == times_s.size());
    AVSI_ASSERT(std::is_sorted(times_s.begin(), times_s.end()));
    if (!(tolerance > 0.0)) {
        cohen_massaro_full(segments, times_s, out);
        return;
    }
    bounded_sum<1>(
        segments.size(), [&](std::size_t, std::size_t i) -> const CmSegment& { return segments[i]; }, times_s,
        tolerance, [&](std::size_t f, std::size_t, double value) { out[f] = value; });
}

void cohen_massaro_bounded_all(const std::array<std::vector<CmSegment>, param_count>& segments,
                               std::span<const double> times_s, std::vector<Frame>& out, double tolerance) {
    AVSI_ASSERT(std::is_sorted(times_s.begin(), times_s.end()));
    out.assign(times_s.size(), Frame{});
    const std::size_t n = segments[0].size();
    bool shared = n > 0 && tolerance > 0.0;
    for (std::size_t p = 1; shared && p < param_count; ++p) {
        shared = segments[p].size() == n;
        for (std::size_t i = 0; shared && i < n; ++i)
            shared = segments[p][i].tau_s == segments[0][i].tau_s && segments[p][i].c == segments[0][i].c;
    }
    if (shared) {
        bounded_sum<static_cast<int>(param_count)>(
            n, [&](std::size_t p, std::size_t i) -> const CmSegment& { return segments[p][i]; }, times_s, tolerance,
            [&](std::size_t f, std::size_t p, double value) { out[f][p] = value; });
        return;
    }
    std::vector<double> values(times_s.size());
    for (std::size_t p = 0; p < param_count; ++p) {
        cohen_massaro_bounded(segments[p], times_s, values, tolerance);
        for (std::size_t k = 0; k < values.size(); ++k) out[k][p] = values[k];
    }
}

std::vector<CmSegment> DominanceModel::segments(const PhoneSequence& phones, Param param) const {
    return std::move(segments_all(phones)[index(param)]);
}

void DominanceModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                              std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    cohen_massaro_bounded_all(segments_all(phones), times_s, out, tolerance);
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
