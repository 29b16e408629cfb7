// The rule-based model (Beskow 1995): targets with unspecified entries,
// linear interpolation across the context, closed-form Gaussian smoothing.
#include "avsi/synth/rule_model.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/synth/target_hold.h"
#include "model_json.h"

namespace avsi::synth {

namespace {

struct Knot {
    double t;
    double value;
};

// Per parameter: the neutral edges and the specified targets at centres.
std::array<std::vector<Knot>, param_count> knots_of(const RuleModel::Table& table, const PhoneSequence& phones,
                                                    std::string_view kind) {
    std::array<std::vector<Knot>, param_count> knots;
    for (std::size_t p = 0; p < param_count; ++p) knots[p].push_back({phones.front().start_s, params()[p].neutral});
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const RuleTarget* target = find_phone_entry(table, phones[i]);
        if (!target) detail::missing_phone(phones[i], i, kind);
        for (std::size_t p = 0; p < param_count; ++p)
            if ((*target)[p]) knots[p].push_back({phones[i].centre_s(), *(*target)[p]});
    }
    for (std::size_t p = 0; p < param_count; ++p) knots[p].push_back({phones.back().end_s, params()[p].neutral});
    return knots;
}

// The piecewise-linear function through the knots, constant outside.
double linear_at(const std::vector<Knot>& knots, double t) {
    if (t <= knots.front().t) return knots.front().value;
    if (t >= knots.back().t) return knots.back().value;
    const auto it = std::upper_bound(knots.begin(), knots.end(), t, [](double x, const Knot& k) { return x < k.t; });
    const Knot& b = *it;
    const Knot& a = *(it - 1);
    return a.value + (b.value - a.value) * (t - a.t) / (b.t - a.t);
}

// (G_σ * ramp)(x) − ramp(x) for ramp(x) = max(x, 0): σφ(x/σ) − |x|Φ(−|x|/σ).
double smoothing_correction(double x, double sigma) {
    const double u = std::abs(x) / sigma;
    const double pdf = std::exp(-0.5 * u * u) / std::sqrt(2.0 * std::numbers::pi);
    const double tail = 0.5 * std::erfc(u / std::numbers::sqrt2);
    return sigma * pdf - std::abs(x) * tail;
}

// The linear track convolved with a Gaussian: f(t) + Σ_k Δs_k·h(t − t_k),
// Δs_k the change of slope at knot k. Knots beyond 10σ add < 1e-22·σ·|Δs|.
double smoothed_at(const std::vector<Knot>& knots, const std::vector<double>& slope_change, double sigma, double t) {
    double v = linear_at(knots, t);
    if (sigma <= 0.0) return v;
    const double reach = 10.0 * sigma;
    auto lo = std::lower_bound(knots.begin(), knots.end(), t - reach, [](const Knot& k, double x) { return k.t < x; });
    for (auto it = lo; it != knots.end() && it->t <= t + reach; ++it) {
        const std::size_t q = static_cast<std::size_t>(it - knots.begin());
        v += slope_change[q] * smoothing_correction(t - it->t, sigma);
    }
    return v;
}

}  // namespace

void RuleModel::interpolated(const PhoneSequence& phones, std::span<const double> times_s,
                             std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    const auto knots = knots_of(m_targets, phones, kind());
    out.assign(times_s.size(), Frame{});
    for (std::size_t p = 0; p < param_count; ++p)
        for (std::size_t k = 0; k < times_s.size(); ++k) out[k][p] = linear_at(knots[p], times_s[k]);
}

void RuleModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s, std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    const auto knots = knots_of(m_targets, phones, kind());
    out.assign(times_s.size(), Frame{});
    for (std::size_t p = 0; p < param_count; ++p) {
        const auto& kn = knots[p];
        std::vector<double> slope_change(kn.size(), 0.0);
        double previous = 0.0;
        for (std::size_t q = 0; q < kn.size(); ++q) {
            const double next = q + 1 < kn.size() ? (kn[q + 1].value - kn[q].value) / (kn[q + 1].t - kn[q].t) : 0.0;
            slope_change[q] = next - previous;
            previous = next;
        }
        for (std::size_t k = 0; k < times_s.size(); ++k)
            out[k][p] = smoothed_at(kn, slope_change, m_sigma_s, times_s[k]);
    }
    if (!m_held.empty()) {
        TargetHoldSettings hold;
        hold.phones = m_held;
        hold.transition_s = std::max(m_sigma_s, 1e-3);
        hold_targets(phones, times_s, m_targets, hold, out);
    }
}

std::string RuleModel::to_json_text() const {
    using detail::json;
    json j = detail::model_header(*this);
    j["smoothing_sigma_s"] = m_sigma_s;
    if (!m_held.empty()) j["held_phones"] = m_held;
    json targets = json::object();
    for (const auto& [key, target] : m_targets) {
        json t = json::object();
        for (const auto& info : params()) {
            const auto& v = target[index(info.param)];
            t[std::string(info.name)] = v ? json(*v) : json(nullptr);
        }
        targets[key] = t;
    }
    j["targets"] = targets;
    return j.dump(2) + "\n";
}

std::map<std::string, RuleTarget, std::less<>> read_rule_targets_tsv(const std::filesystem::path& path) {
    CsvOptions options;
    options.delimiter = '\t';
    const CsvTable table = read_csv(path, options);
    const std::string file = path.string();
    const std::size_t phone_col = table.require_column("phone");
    std::array<std::size_t, param_count> cols{};
    for (const auto& info : params()) cols[index(info.param)] = table.require_column(info.name);
    DiagnosticList problems;
    std::map<std::string, RuleTarget, std::less<>> out;
    for (const auto& row : table.rows) {
        if (row.fields.size() != table.header.size()) {
            problems.add(file, row.line, 0, "",
                         fmt::format("expected {} fields, got {}", table.header.size(), row.fields.size()));
            continue;
        }
        const std::string& key = row.fields[phone_col];
        if (const auto problem = detail::phone_key_problem(key)) {
            problems.add(file, row.line, static_cast<int>(phone_col) + 1, "phone", *problem);
            continue;
        }
        if (out.count(key)) {
            problems.add(file, row.line, static_cast<int>(phone_col) + 1, "phone",
                         fmt::format("phone \"{}\" listed twice", key));
            continue;
        }
        RuleTarget target;
        for (const auto& info : params()) {
            const std::size_t c = cols[index(info.param)];
            const std::string& cell = row.fields[c];
            if (cell == "-") continue;
            const auto v = parse_double(cell);
            if (!v || *v < info.min || *v > info.max) {
                problems.add(file, row.line, static_cast<int>(c) + 1, std::string(info.name),
                             fmt::format("expected a number in [{}, {}] or \"-\" (unspecified), got \"{}\"",
                                         info.min, info.max, cell));
                continue;
            }
            target[index(info.param)] = *v;
        }
        out[key] = target;
    }
    problems.throw_if_any();
    return out;
}

namespace detail {

std::unique_ptr<ControlModel> load_rule(const json& root, const std::filesystem::path& path, JsonReader& reader) {
    reader.check_keys(root, {"kind", "version", "provenance", "smoothing_sigma_s", "held_phones", "targets", "targets_file"},
                      "");
    double sigma = 0.025;
    if (auto v = reader.number_field(root, "smoothing_sigma_s", "/smoothing_sigma_s", 0.0, 1.0)) sigma = *v;
    std::set<std::string, std::less<>> held;
    if (root.contains("held_phones")) {
        const json& h = root["held_phones"];
        if (!h.is_array()) reader.error("/held_phones", "expected an array of phone symbols, got " + h.dump());
        else
            for (std::size_t k = 0; k < h.size(); ++k) {
                const std::string pointer = "/held_phones/" + std::to_string(k);
                if (!h[k].is_string()) reader.error(pointer, "expected a phone symbol, got " + h[k].dump());
                else if (reader.phone_key(h[k].get<std::string>(), pointer)) held.insert(h[k].get<std::string>());
            }
    }
    RuleModel::Table table;
    const bool embedded = root.contains("targets"), external = root.contains("targets_file");
    if (embedded == external) {
        reader.error("/targets", "expected exactly one of \"targets\" (embedded) and \"targets_file\" (a TSV)");
        return nullptr;
    }
    if (external) {
        // One TSV, or several (English's table and a language's additions):
        // a phone in two of them is an error.
        const json& ref = root["targets_file"];
        std::vector<std::string> files;
        if (ref.is_string()) files.push_back(ref.get<std::string>());
        else if (ref.is_array() && !ref.empty() && std::all_of(ref.begin(), ref.end(), [](const json& f) { return f.is_string(); }))
            for (const auto& f : ref) files.push_back(f.get<std::string>());
        else {
            reader.error("/targets_file", "expected a TSV file name or an array of them, got " + ref.dump());
            return nullptr;
        }
        for (std::size_t k = 0; k < files.size(); ++k) {
            std::filesystem::path p = files[k];
            if (p.is_relative()) p = path.parent_path() / p;
            try {
                for (auto& [phone, target] : read_rule_targets_tsv(p)) {
                    if (table.count(phone))
                        reader.error(ref.is_array() ? "/targets_file/" + std::to_string(k) : "/targets_file",
                                     fmt::format("phone \"{}\" has a row in an earlier targets file too", phone));
                    table[phone] = target;
                }
            } catch (const InputError& e) {
                for (const auto& d : e.diagnostics()) reader.error("/targets_file", d.format());
                return nullptr;
            }
        }
    } else {
        std::vector<std::string> names;
        for (const auto& info : params()) names.emplace_back(info.name);
        for (const auto& [key, entry] : root["targets"].items()) {
            const std::string base = "/targets/" + pointer_token(key);
            if (!reader.phone_key(key, base)) continue;
            reader.check_keys(entry, names, base, "parameter");
            RuleTarget target;
            for (const auto& info : params()) {
                const std::string pp = base + "/" + std::string(info.name);
                const json* v = reader.require(entry, std::string(info.name), pp);
                if (!v || v->is_null()) continue;
                if (auto x = reader.param_value(*v, info.param, pp)) target[index(info.param)] = *x;
            }
            table[key] = target;
        }
    }
    for (const auto& phone : held)
        if (!table.count(phone)) reader.error("/held_phones", "phone \"" + phone + "\" has no target row to hold");
    return std::make_unique<RuleModel>(std::move(table), sigma, std::move(held));
}

}  // namespace detail
}  // namespace avsi::synth
