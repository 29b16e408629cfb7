// Öhman's model (Beskow §4.3, eq. 15–17): vowel track (eq. 17) plus
// consonant gestures (eq. 16) with cubic blends, the model's one forward
// pass (ohman_blends here, ohman_value in ohman.h), and the model file; edge
// and silence decisions in ohman.h. Training differentiates the same pass
// (eq. 18–20, learn/src/training.cpp).
#include "avsi/synth/ohman.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "model_json.h"

namespace avsi::synth {

double smoothstep(double x) {
    if (x <= 0.0) return 0.0;
    if (x >= 1.0) return 1.0;
    return x * x * (3.0 - 2.0 * x);
}

VowelBlend ohman_vowel_blend(std::span<const double> anchor_centres, double t) {
    const std::size_t m = anchor_centres.size();
    if (m == 0) return {};
    const long j = static_cast<long>(std::upper_bound(anchor_centres.begin(), anchor_centres.end(), t) -
                                     anchor_centres.begin()) - 1;
    if (j < 0) return {0, -1, 1.0, 0.0};
    if (static_cast<std::size_t>(j) + 1 >= m) return {static_cast<long>(m) - 1, -1, 1.0, 0.0};
    const double a = anchor_centres[static_cast<std::size_t>(j)], b = anchor_centres[static_cast<std::size_t>(j) + 1];
    const double s = smoothstep((t - a) / (b - a));
    return {j, j + 1, 1.0 - s, s};
}

double ohman_consonant_blend(std::span<const double> c, std::size_t i, double t) {
    const double tau = c[i];
    if (t <= tau) {
        if (i == 0) return 1.0;
        return smoothstep((t - c[i - 1]) / (tau - c[i - 1]));
    }
    if (i + 1 == c.size()) return 1.0;
    return smoothstep((c[i + 1] - t) / (c[i + 1] - tau));
}

namespace {

bool is_anchor(const Phone& phone) { return phone.symbol == "sil" || detail::is_vowel_symbol(phone.symbol); }

// Index n of the last centre <= t, or -1 if t is before the first centre.
long bracket(std::span<const double> centres, double t) {
    return static_cast<long>(std::upper_bound(centres.begin(), centres.end(), t) - centres.begin()) - 1;
}

// The resolved utterance: centres, and per segment its vowel targets or
// consonant parameters.
struct Resolved {
    std::vector<double> centres;
    std::vector<bool> anchor;
    std::vector<double> anchor_centres;
    std::vector<const Frame*> anchor_targets;
    std::vector<const OhmanConsonant*> consonant;  // per segment; nullptr for anchors
};

}  // namespace

OhmanBlends ohman_blends(std::span<const double> centres, std::span<const double> anchor_centres,
                         const std::vector<bool>& anchor, double t) {
    OhmanBlends b;
    b.vowel = ohman_vowel_blend(anchor_centres, t);
    const long n = bracket(centres, t);
    for (long i : {n, n + 1}) {
        if (i < 0 || static_cast<std::size_t>(i) >= centres.size() || anchor[static_cast<std::size_t>(i)]) continue;
        const double blend = ohman_consonant_blend(centres, static_cast<std::size_t>(i), t);
        if (blend == 0.0) continue;
        b.consonant[static_cast<std::size_t>(b.consonants)] = static_cast<std::size_t>(i);
        b.k[static_cast<std::size_t>(b.consonants)] = blend;
        ++b.consonants;
    }
    return b;
}

void OhmanModel::vowel_track(const PhoneSequence& phones, std::span<const double> times_s,
                             std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    Resolved r;
    for (std::size_t i = 0; i < phones.size(); ++i) {
        if (!is_anchor(phones[i])) continue;
        const Frame* a = find_phone_entry(m_vowels, phones[i]);
        if (!a) detail::missing_phone(phones[i], i, kind());
        r.anchor_centres.push_back(phones[i].centre_s());
        r.anchor_targets.push_back(a);
    }
    out.resize(times_s.size());
    for (std::size_t k = 0; k < times_s.size(); ++k) {
        const VowelBlend b = ohman_vowel_blend(r.anchor_centres, times_s[k]);
        for (const auto& info : params()) {
            const std::size_t p = index(info.param);
            out[k][p] = ohman_vowel_value(b, info.neutral,
                                          [&](long j) { return (*r.anchor_targets[static_cast<std::size_t>(j)])[p]; });
        }
    }
}

void OhmanModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                          std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    Resolved r;
    r.consonant.assign(phones.size(), nullptr);
    for (std::size_t i = 0; i < phones.size(); ++i) {
        r.centres.push_back(phones[i].centre_s());
        r.anchor.push_back(is_anchor(phones[i]));
        if (r.anchor.back()) {
            const Frame* a = find_phone_entry(m_vowels, phones[i]);
            if (!a) detail::missing_phone(phones[i], i, kind());
            r.anchor_centres.push_back(phones[i].centre_s());
            r.anchor_targets.push_back(a);
        } else {
            const OhmanConsonant* c = find_phone_entry(m_consonants, phones[i]);
            if (!c) detail::missing_phone(phones[i], i, kind());
            r.consonant[i] = c;
        }
    }
    out.resize(times_s.size());
    for (std::size_t k = 0; k < times_s.size(); ++k) {
        const OhmanBlends b = ohman_blends(r.centres, r.anchor_centres, r.anchor, times_s[k]);
        for (const auto& info : params()) {
            const std::size_t p = index(info.param);
            out[k][p] = ohman_value(
                            b, info.neutral,
                            [&](long j) { return (*r.anchor_targets[static_cast<std::size_t>(j)])[p]; },
                            [&](std::size_t i) {
                                const OhmanConsonantParam& q = (*r.consonant[i])[p];
                                return std::pair{q.target, q.coarticulation_factor};
                            })
                            .z;
        }
    }
}

std::string OhmanModel::to_json_text() const {
    using detail::json;
    json j = detail::model_header(*this);
    json vowels = json::object();
    for (const auto& [key, targets] : m_vowels) {
        json t = json::object();
        for (const auto& info : params()) t[std::string(info.name)] = targets[index(info.param)];
        vowels[key] = t;
    }
    json consonants = json::object();
    for (const auto& [key, c] : m_consonants) {
        json t = json::object();
        for (const auto& info : params()) {
            const auto& q = c[index(info.param)];
            t[std::string(info.name)] = json{{"target", q.target}, {"w", q.coarticulation_factor}};
        }
        consonants[key] = t;
    }
    j["vowels"] = vowels;
    j["consonants"] = consonants;
    return j.dump(2) + "\n";
}

namespace detail {

std::unique_ptr<ControlModel> load_ohman(const json& root, const std::filesystem::path&, JsonReader& reader) {
    reader.check_keys(root, {"kind", "version", "provenance", "vowels", "consonants"}, "");
    std::vector<std::string> names;
    for (const auto& info : params()) names.emplace_back(info.name);
    auto base_of = [](const std::string& key) {
        return (key.size() > 1 && (key.back() == '0' || key.back() == '1')) ? key.substr(0, key.size() - 1) : key;
    };
    OhmanModel::VowelTable vowels;
    if (const json* node = reader.require(root, "vowels", "/vowels")) {
        for (const auto& [key, entry] : node->items()) {
            const std::string base = "/vowels/" + pointer_token(key);
            if (!reader.phone_key(key, base)) continue;
            if (base_of(key) != "sil" && !is_vowel_symbol(base_of(key))) {
                reader.error(base, fmt::format("\"{}\" is a consonant; it belongs under /consonants", key));
                continue;
            }
            reader.check_keys(entry, names, base, "parameter");
            Frame f{};
            for (const auto& info : params()) {
                const std::string pp = base + "/" + std::string(info.name);
                if (const json* v = reader.require(entry, std::string(info.name), pp))
                    if (auto x = reader.param_value(*v, info.param, pp)) f[index(info.param)] = *x;
            }
            vowels[key] = f;
        }
    }
    OhmanModel::ConsonantTable consonants;
    if (const json* node = reader.require(root, "consonants", "/consonants")) {
        for (const auto& [key, entry] : node->items()) {
            const std::string base = "/consonants/" + pointer_token(key);
            if (!reader.phone_key(key, base)) continue;
            if (base_of(key) == "sil" || is_vowel_symbol(base_of(key))) {
                reader.error(base, fmt::format("\"{}\" is a vowel or silence; it belongs under /vowels", key));
                continue;
            }
            reader.check_keys(entry, names, base, "parameter");
            OhmanConsonant c{};
            for (const auto& info : params()) {
                const std::string pp = base + "/" + std::string(info.name);
                const json* q = reader.require(entry, std::string(info.name), pp);
                if (!q) continue;
                reader.check_keys(*q, {"target", "w"}, pp);
                if (const json* t = reader.require(*q, "target", pp + "/target"))
                    if (auto x = reader.param_value(*t, info.param, pp + "/target")) c[index(info.param)].target = *x;
                if (auto w = reader.number_field(*q, "w", pp + "/w", 0.0, 1.0))
                    c[index(info.param)].coarticulation_factor = *w;
            }
            consonants[key] = c;
        }
    }
    return std::make_unique<OhmanModel>(std::move(vowels), std::move(consonants));
}

}  // namespace detail
}  // namespace avsi::synth
