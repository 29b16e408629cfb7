// The MPEG-4 Cohen-Massaro variant (Charisma paper §3.4, eq. 5–8): viseme
// sets, α from normalised ellipse areas, and the model file.
#include "avsi/synth/mpeg4_cohen_massaro.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "model_json.h"

namespace avsi::synth {

double Viseme::area_mm2() const { return std::numbers::pi * width_mm * height_mm; }

std::vector<double> VisemeSet::normalised_areas() const {
    double largest = 0.0;
    for (const auto& v : visemes) largest = std::max(largest, v.area_mm2());
    AVSI_ASSERT(largest > 0.0);
    std::vector<double> out;
    for (const auto& v : visemes) out.push_back(v.area_mm2() / largest);
    return out;
}

const Viseme& VisemeSet::viseme_of(std::string_view phone_symbol) const {
    const auto it = phone_to_viseme.find(phone_symbol);
    if (it == phone_to_viseme.end())
        throw InputError(Diagnostic{"", 0, 0, "phone",
                                    fmt::format("viseme set \"{}\" has no viseme for phone \"{}\"", name, phone_symbol)});
    return visemes[it->second];
}

VisemeSet load_viseme_set(const std::filesystem::path& path) {
    using namespace detail;
    const json root = parse_json_file(path);
    DiagnosticList problems;
    JsonReader reader(path.string(), problems);
    VisemeSet set;
    reader.check_keys(root, {"name", "source", "language", "visemes"}, "");
    if (auto v = reader.string_field(root, "name", "/name")) set.name = *v;
    if (root.contains("language"))
        if (auto v = reader.string_field(root, "language", "/language")) set.language = *v;
    if (auto v = reader.string_field(root, "source", "/source")) set.source = *v;
    const json* list = reader.require(root, "visemes", "/visemes");
    std::vector<std::string> names;
    for (const auto& info : params()) names.emplace_back(info.name);
    if (list && (!list->is_array() || list->empty())) reader.error("/visemes", "expected a non-empty array");
    if (list && list->is_array()) {
        for (std::size_t i = 0; i < list->size(); ++i) {
            const json& node = (*list)[i];
            const std::string base = fmt::format("/visemes/{}", i);
            reader.check_keys(node, {"id", "name", "phones", "width_mm", "height_mm", "targets"}, base);
            Viseme v;
            if (const json* id = reader.require(node, "id", base + "/id")) {
                if (!id->is_number_integer())
                    reader.error(base + "/id", fmt::format("expected an integer, got {}", id->dump()));
                else
                    v.id = id->get<int>();
            }
            if (auto s = reader.string_field(node, "name", base + "/name")) v.name = *s;
            if (auto w = reader.number_field(node, "width_mm", base + "/width_mm", 0.0, 200.0, true)) v.width_mm = *w;
            if (auto h = reader.number_field(node, "height_mm", base + "/height_mm", 0.0, 200.0, true)) v.height_mm = *h;
            if (const json* ph = reader.require(node, "phones", base + "/phones")) {
                if (!ph->is_array()) reader.error(base + "/phones", "expected an array of phone symbols");
                else
                    for (std::size_t q = 0; q < ph->size(); ++q) {
                        const std::string pp = fmt::format("{}/phones/{}", base, q);
                        if (!(*ph)[q].is_string()) {
                            reader.error(pp, fmt::format("expected a phone symbol, got {}", (*ph)[q].dump()));
                            continue;
                        }
                        const std::string sym = (*ph)[q].get<std::string>();
                        if (!is_phone_symbol(sym)) {
                            reader.phone_key(sym, pp);
                            continue;
                        }
                        if (set.phone_to_viseme.count(sym)) {
                            reader.error(pp, fmt::format("phone \"{}\" is already mapped to viseme \"{}\"", sym,
                                                         set.visemes[set.phone_to_viseme[sym]].name));
                            continue;
                        }
                        v.phones.push_back(sym);
                        set.phone_to_viseme[sym] = set.visemes.size();
                    }
            }
            if (const json* targets = reader.require(node, "targets", base + "/targets")) {
                reader.check_keys(*targets, names, base + "/targets", "parameter");
                for (const auto& info : params()) {
                    const std::string pp = base + "/targets/" + std::string(info.name);
                    if (const json* t = reader.require(*targets, std::string(info.name), pp))
                        if (auto val = reader.param_value(*t, info.param, pp)) v.targets[index(info.param)] = *val;
                }
            }
            set.visemes.push_back(std::move(v));
        }
    }
    if (!PhoneInventory::builtin().has_language(set.language))
        reader.error("/language", fmt::format("no phone table for language \"{}\" (protocols/languages/)", set.language));
    else
        for (const auto& sym : PhoneInventory::builtin().language_phones(set.language))
            if (!set.phone_to_viseme.count(sym))
                reader.error("/visemes", fmt::format("phone \"{}\" is not mapped to any viseme", sym));
    problems.throw_if_any();
    return set;
}

std::string viseme_set_json_text(const VisemeSet& set) {
    nlohmann::ordered_json root;
    root["name"] = set.name;
    root["source"] = set.source;
    if (set.language != "en") root["language"] = set.language;
    root["visemes"] = nlohmann::ordered_json::array();
    for (const auto& v : set.visemes) {
        nlohmann::ordered_json targets = nlohmann::ordered_json::object();
        for (const auto& info : params()) targets[std::string(info.name)] = v.targets[index(info.param)];
        nlohmann::ordered_json item;
        item["id"] = v.id;
        item["name"] = v.name;
        item["phones"] = v.phones;
        item["width_mm"] = v.width_mm;
        item["height_mm"] = v.height_mm;
        item["targets"] = std::move(targets);
        root["visemes"].push_back(std::move(item));
    }
    return root.dump(2) + "\n";
}

CmSegment mpeg4_segment(double centre_s, double t0_s, double target, double alpha,
                        double theta_anticipatory_per_s, double theta_carryover_per_s) {
    // Eq. 6: the peak at the segment centre plus t0; eq. 5: c = 1.
    return {centre_s + t0_s, target, alpha, theta_anticipatory_per_s, theta_carryover_per_s, 1.0};
}

Mpeg4CohenMassaroModel::Mpeg4CohenMassaroModel(VisemeSet visemes, std::string viseme_set_ref,
                                               Mpeg4CmSettings settings)
    : m_visemes(std::move(visemes)), m_viseme_set_ref(std::move(viseme_set_ref)), m_settings(std::move(settings)) {
    for (double a : m_visemes.normalised_areas()) m_alphas.push_back(std::max(a, m_settings.alpha_floor));
}

std::array<std::vector<CmSegment>, param_count> Mpeg4CohenMassaroModel::segments_all(
    const PhoneSequence& phones) const {
    std::array<std::vector<CmSegment>, param_count> out;
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const auto it = m_visemes.phone_to_viseme.find(phones[i].symbol);
        if (it == m_visemes.phone_to_viseme.end()) detail::missing_phone(phones[i], i, kind());
        const Viseme& v = m_visemes.visemes[it->second];
        double t0 = m_settings.t0_s;
        if (const auto o = m_settings.t0_s_by_viseme.find(v.name); o != m_settings.t0_s_by_viseme.end()) t0 = o->second;
        const double centre = phones[i].start_s + 0.5 * phones[i].duration_s();
        for (std::size_t p = 0; p < param_count; ++p)
            out[p].push_back(mpeg4_segment(centre, t0, v.targets[p], m_alphas[it->second],
                                           m_settings.theta_anticipatory_per_s, m_settings.theta_carryover_per_s));
    }
    return out;
}

std::string Mpeg4CohenMassaroModel::to_json_text() const {
    using detail::json;
    json j = detail::model_header(*this);
    j["viseme_set"] = m_viseme_set_ref;
    j["theta_anticipatory_per_s"] = m_settings.theta_anticipatory_per_s;
    j["theta_carryover_per_s"] = m_settings.theta_carryover_per_s;
    j["t0_s"] = m_settings.t0_s;
    json by = json::object();
    for (const auto& [k, v] : m_settings.t0_s_by_viseme) by[k] = v;
    j["t0_s_by_viseme"] = by;
    j["alpha_floor"] = m_settings.alpha_floor;
    return j.dump(2) + "\n";
}

namespace detail {

std::unique_ptr<ControlModel> load_mpeg4_cohen_massaro(const json& root, const std::filesystem::path& path,
                                                       JsonReader& reader) {
    reader.check_keys(root,
                      {"kind", "version", "provenance", "viseme_set", "theta_anticipatory_per_s",
                       "theta_carryover_per_s", "t0_s", "t0_s_by_viseme", "alpha_floor"},
                      "");
    Mpeg4CmSettings settings;
    if (auto v = reader.number_field(root, "theta_anticipatory_per_s", "/theta_anticipatory_per_s", 0.0, 1e6, true))
        settings.theta_anticipatory_per_s = *v;
    if (auto v = reader.number_field(root, "theta_carryover_per_s", "/theta_carryover_per_s", 0.0, 1e6, true))
        settings.theta_carryover_per_s = *v;
    if (root.contains("t0_s"))
        if (auto v = reader.number(root["t0_s"], "/t0_s", -1.0, 1.0)) settings.t0_s = *v;
    if (root.contains("alpha_floor"))
        if (auto v = reader.number(root["alpha_floor"], "/alpha_floor", 0.0, 1.0)) settings.alpha_floor = *v;
    const auto ref = reader.string_field(root, "viseme_set", "/viseme_set");
    if (!ref) return nullptr;
    std::filesystem::path set_path = *ref;
    if (set_path.is_relative()) set_path = path.parent_path() / set_path;
    VisemeSet set;
    try {
        set = load_viseme_set(set_path);
    } catch (const InputError& e) {
        for (const auto& d : e.diagnostics()) reader.error("/viseme_set", d.format());
        return nullptr;
    }
    if (root.contains("t0_s_by_viseme")) {
        const json& by = root["t0_s_by_viseme"];
        std::vector<std::string> names;
        for (const auto& v : set.visemes) names.push_back(v.name);
        if (!by.is_object()) reader.error("/t0_s_by_viseme", "expected an object keyed by viseme name");
        else {
            reader.check_keys(by, names, "/t0_s_by_viseme", "viseme");
            for (const auto& [k, v] : by.items())
                if (std::find(names.begin(), names.end(), k) != names.end())
                    if (auto t = reader.number(v, "/t0_s_by_viseme/" + pointer_token(k), -1.0, 1.0))
                        settings.t0_s_by_viseme[k] = *t;
        }
    }
    return std::make_unique<Mpeg4CohenMassaroModel>(std::move(set), *ref, std::move(settings));
}

}  // namespace detail
}  // namespace avsi::synth
