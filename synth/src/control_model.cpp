// The control-model interface, model-file dispatch and the JSON helpers the
// per-kind loaders share.
#include "avsi/synth/control_model.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "model_json.h"

namespace avsi::synth {

Trajectory ControlModel::synthesize(const PhoneSequence& phones, double fps) const {
    if (!(fps > 0.0) || !std::isfinite(fps))
        throw InputError(Diagnostic{"", 0, 0, "fps", fmt::format("expected a positive frame rate, got {}", fps)});
    check_phones_for_synthesis(phones);
    Trajectory out;
    out.fps = fps;
    const std::size_t n = frame_count(phones.back().end_s, fps);
    std::vector<double> times(n);
    for (std::size_t k = 0; k < n; ++k) times[k] = static_cast<double>(k) / fps;
    evaluate(phones, times, out.frames);
    return out;
}

const std::vector<std::string>& model_kinds() {
    static const std::vector<std::string> kinds{"rule", "cohen-massaro", "mpeg4-cohen-massaro", "ohman", "ann"};
    return kinds;
}

std::unique_ptr<ControlModel> load_model(const std::filesystem::path& path) {
    return with_json_context(path, [&] { return detail::load_model_json(path); });
}

namespace detail {
std::unique_ptr<ControlModel> load_model_json(const std::filesystem::path& path) {
    const json root = parse_json_file(path);
    DiagnosticList problems;
    JsonReader reader(path.string(), problems);
    if (!root.is_object()) {
        reader.error("", fmt::format("expected a JSON object, got {}", root.type_name()));
        problems.throw_if_any();
    }
    const auto kind = reader.string_field(root, "kind", "/kind");
    if (const json* version = reader.require(root, "version", "/version")) {
        if (!version->is_number_integer() || version->get<long long>() != 1)
            reader.error("/version", fmt::format("expected 1, got {}", version->dump()));
    }
    if (!kind) {
        problems.throw_if_any();
    }
    std::unique_ptr<ControlModel> model;
    if (*kind == "cohen-massaro")
        model = load_cohen_massaro(root, path, reader);
    else if (*kind == "mpeg4-cohen-massaro")
        model = load_mpeg4_cohen_massaro(root, path, reader);
    else if (*kind == "ohman")
        model = load_ohman(root, path, reader);
    else if (*kind == "rule")
        model = load_rule(root, path, reader);
    else if (*kind == "ann")
        model = load_ann(root, path, reader);
    else {
        std::string message = fmt::format("expected one of {}, got \"{}\"", fmt::join(model_kinds(), ", "), *kind);
        const std::string guess = closest_match(*kind, model_kinds());
        if (!guess.empty()) message += fmt::format(" (did you mean \"{}\"?)", guess);
        reader.error("/kind", message);
    }
    ModelProvenance provenance = provenance_from_json(root, reader);
    problems.throw_if_any();
    AVSI_ASSERT(model);
    model->set_provenance(std::move(provenance));
    return model;
}
}  // namespace detail

void save_model(const ControlModel& model, const std::filesystem::path& path) {
    write_text_file(path, model.to_json_text());
}

void check_phones_for_synthesis(const PhoneSequence& phones, std::string_view source) {
    const std::string where(source);
    if (phones.empty()) throw InputError(Diagnostic{where, 0, 0, "phones", "expected at least one phone, got none"});
    DiagnosticList problems;
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const Phone& p = phones[i];
        const std::string field = fmt::format("phone {} ('{}')", i + 1, p.symbol);
        if (!std::isfinite(p.start_s) || !std::isfinite(p.end_s) || !(p.end_s > p.start_s))
            problems.add(where, 0, 0, field,
                         fmt::format("expected end > start, got start {} s, end {} s", p.start_s, p.end_s));
        else if (i > 0 && p.start_s < phones[i - 1].end_s - 1e-6)
            problems.add(where, 0, 0, field,
                         fmt::format("expected to start at or after the previous phone's end {} s, got {} s",
                                     phones[i - 1].end_s, p.start_s));
    }
    if (phones.front().start_s < 0.0)
        problems.add(where, 0, 0, "phone 1", fmt::format("expected start >= 0 s, got {} s", phones.front().start_s));
    problems.throw_if_any();
}

namespace detail {

std::string pointer_token(const std::string& key) {
    std::string out;
    for (char ch : key) {
        if (ch == '~')
            out += "~0";
        else if (ch == '/')
            out += "~1";
        else
            out += ch;
    }
    return out;
}

const json* JsonReader::require(const json& obj, const std::string& key, const std::string& pointer) {
    if (!obj.is_object()) return nullptr;
    const auto it = obj.find(key);
    if (it == obj.end()) {
        error(pointer, "missing field");
        return nullptr;
    }
    return &*it;
}

std::optional<double> JsonReader::number(const json& value, const std::string& pointer, double min, double max,
                                         bool min_exclusive) {
    if (!value.is_number()) {
        error(pointer, fmt::format("expected a number, got {}", value.dump()));
        return std::nullopt;
    }
    const double v = value.get<double>();
    const bool below = min_exclusive ? !(v > min) : !(v >= min);
    if (below || !(v <= max) || !std::isfinite(v)) {
        error(pointer, fmt::format("expected a number in {}{}, {}], got {}", min_exclusive ? "(" : "[", min, max, v));
        return std::nullopt;
    }
    return v;
}

std::optional<double> JsonReader::number_field(const json& obj, const std::string& key, const std::string& pointer,
                                               double min, double max, bool min_exclusive) {
    const json* v = require(obj, key, pointer);
    if (!v) return std::nullopt;
    return number(*v, pointer, min, max, min_exclusive);
}

std::optional<std::string> JsonReader::string_field(const json& obj, const std::string& key,
                                                    const std::string& pointer) {
    const json* v = require(obj, key, pointer);
    if (!v) return std::nullopt;
    if (!v->is_string()) {
        error(pointer, fmt::format("expected a string, got {}", v->dump()));
        return std::nullopt;
    }
    return v->get<std::string>();
}

void JsonReader::check_keys(const json& obj, const std::vector<std::string>& allowed, const std::string& pointer,
                            const std::string& what) {
    if (!obj.is_object()) return;
    for (const auto& [key, value] : obj.items()) {
        if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
        std::string message = fmt::format("unknown {} \"{}\"", what, key);
        const std::string guess = closest_match(key, allowed);
        if (!guess.empty()) message += fmt::format(" (did you mean \"{}\"?)", guess);
        error(pointer + "/" + pointer_token(key), message);
    }
}

std::optional<double> JsonReader::param_value(const json& value, Param param, const std::string& pointer) {
    const ParamInfo& info = param_info(param);
    return number(value, pointer, info.min, info.max);
}

std::optional<std::string> phone_key_problem(const std::string& key) {
    if (is_phone_symbol(key)) return std::nullopt;
    if (key.size() > 1 && (key.back() == '0' || key.back() == '1')) {
        const std::string base = key.substr(0, key.size() - 1);
        if (is_vowel_symbol(base)) return std::nullopt;
        if (is_phone_symbol(base)) return fmt::format("stress digit on \"{}\": only vowels take 0/1", base);
    }
    std::string message = fmt::format("unknown phone \"{}\" (expected a project phone: an ARPAbet base symbol, "
                                      "a vowel with stress 0/1, or sil)", key);
    const std::string guess = closest_match(key, phone_symbols());
    if (!guess.empty()) message += fmt::format("; did you mean \"{}\"?", guess);
    return message;
}

bool JsonReader::phone_key(const std::string& key, const std::string& pointer) {
    if (const auto problem = phone_key_problem(key)) {
        error(pointer, *problem);
        return false;
    }
    return true;
}

json provenance_to_json(const ModelProvenance& p) {
    json errors = json::object();
    for (const auto& [k, v] : p.errors) errors[k] = v;
    return json{{"method", p.method}, {"data", p.data}, {"split", p.split}, {"errors", errors}, {"notes", p.notes}};
}

ModelProvenance provenance_from_json(const json& root, JsonReader& reader) {
    ModelProvenance p;
    const json* node = reader.require(root, "provenance", "/provenance");
    if (!node) return p;
    if (!node->is_object()) {
        reader.error("/provenance", fmt::format("expected an object, got {}", node->dump()));
        return p;
    }
    reader.check_keys(*node, {"method", "data", "split", "errors", "notes"}, "/provenance");
    if (auto m = reader.string_field(*node, "method", "/provenance/method")) p.method = *m;
    for (const char* key : {"data", "split", "notes"}) {
        const auto it = node->find(key);
        if (it == node->end()) continue;
        if (!it->is_string()) {
            reader.error(std::string("/provenance/") + key, fmt::format("expected a string, got {}", it->dump()));
            continue;
        }
        std::string& target = std::string(key) == "data" ? p.data : std::string(key) == "split" ? p.split : p.notes;
        target = it->get<std::string>();
    }
    if (const auto it = node->find("errors"); it != node->end()) {
        if (!it->is_object()) {
            reader.error("/provenance/errors", fmt::format("expected an object of numbers, got {}", it->dump()));
        } else {
            for (const auto& [k, v] : it->items()) {
                if (!v.is_number())
                    reader.error("/provenance/errors/" + pointer_token(k),
                                 fmt::format("expected a number, got {}", v.dump()));
                else
                    p.errors[k] = v.get<double>();
            }
        }
    }
    return p;
}

json model_header(const ControlModel& model) {
    json j = json::object();
    j["kind"] = std::string(model.kind());
    j["version"] = 1;
    j["provenance"] = provenance_to_json(model.provenance());
    return j;
}

bool is_vowel_symbol(std::string_view symbol) {
    const auto& inventory = PhoneInventory::builtin();
    return inventory.contains(symbol) && inventory.is_vowel(symbol);
}

bool is_phone_symbol(std::string_view symbol) { return PhoneInventory::builtin().contains(symbol); }

std::vector<std::string> phone_symbols() {
    std::vector<std::string> out;
    for (const auto& symbol : PhoneInventory::builtin().language_phones("en")) out.push_back(symbol);
    return out;
}

json parse_json_file(const std::filesystem::path& path) { return avsi::read_json_file(path); }

void missing_phone(const Phone& phone, std::size_t segment, std::string_view kind) {
    // A phone another language added: the model was trained without it.
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::string languages;
    if (inventory.contains(phone.symbol) && inventory.info(phone.symbol).language != "en")
        for (const auto& code : inventory.languages()) {
            const auto& table = inventory.language_phones(code);
            if (std::find(table.begin(), table.end(), phone.symbol) != table.end())
                languages += (languages.empty() ? "" : ", ") + code;
        }
    const std::string hint =
        languages.empty() ? std::string()
                          : fmt::format(" (a phone of the {} table: use that language's models, protocols/models/"
                                        "<lang>/, or train one on `avsi corpus reference --language <lang>`)",
                                        languages);
    throw InputError(Diagnostic{"", 0, 0, fmt::format("phone {} ('{}' at {:.3f} s)", segment + 1, phone.symbol, phone.start_s),
                                fmt::format("the {} model has no entry for phone \"{}\"{}", kind, phone.symbol, hint)});
}

}  // namespace detail
}  // namespace avsi::synth
