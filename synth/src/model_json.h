// Internal: JSON reading helpers shared by the model loaders. Every problem
// becomes a Diagnostic naming the file and the JSON pointer of the field.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/synth/control_model.h"

namespace avsi::synth::detail {

using nlohmann::json;

class JsonReader {
public:
    JsonReader(std::string path, DiagnosticList& problems) : m_path(std::move(path)), m_problems(problems) {}

    void error(const std::string& pointer, std::string message) {
        m_problems.add(m_path, 0, 0, pointer, std::move(message));
    }

    // obj[key] if present, else an error "missing field" and nullptr.
    const json* require(const json& obj, const std::string& key, const std::string& pointer);
    // A number in [min, max] (exclusive at min when min_exclusive) or nullopt.
    std::optional<double> number(const json& value, const std::string& pointer, double min, double max,
                                 bool min_exclusive = false);
    std::optional<double> number_field(const json& obj, const std::string& key, const std::string& pointer,
                                       double min, double max, bool min_exclusive = false);
    std::optional<std::string> string_field(const json& obj, const std::string& key,
                                            const std::string& pointer);
    // Reports keys of `obj` not in `allowed`, with "did you mean".
    void check_keys(const json& obj, const std::vector<std::string>& allowed, const std::string& pointer,
                    const std::string& what = "field");
    // A parameter value in the parameter's range.
    std::optional<double> param_value(const json& value, Param param, const std::string& pointer);
    // True if `key` is a project phone key ("AA", "AA1", "P", "sil"); else an error.
    bool phone_key(const std::string& key, const std::string& pointer);

    const std::string& path() const { return m_path; }

private:
    std::string m_path;
    DiagnosticList& m_problems;
};

// Why `key` is not a project phone key ("AA", "AA1", "P", "sil"), or nullopt.
std::optional<std::string> phone_key_problem(const std::string& key);

// JSON pointer escaping of one reference token.
std::string pointer_token(const std::string& key);

json provenance_to_json(const ModelProvenance& provenance);
ModelProvenance provenance_from_json(const json& root, JsonReader& reader);
// The common head of a model file: kind, version, provenance.
json model_header(const ControlModel& model);

// The project's vowel symbols (from the phone inventory).
bool is_vowel_symbol(std::string_view symbol);
// A base symbol of the project phone set.
bool is_phone_symbol(std::string_view symbol);
std::vector<std::string> phone_symbols();

// Per-kind loaders (in each model's source). `path` is the model file.
std::unique_ptr<ControlModel> load_cohen_massaro(const json& root, const std::filesystem::path& path,
                                                 JsonReader& reader);
std::unique_ptr<ControlModel> load_mpeg4_cohen_massaro(const json& root, const std::filesystem::path& path,
                                                       JsonReader& reader);
std::unique_ptr<ControlModel> load_ohman(const json& root, const std::filesystem::path& path,
                                         JsonReader& reader);
std::unique_ptr<ControlModel> load_rule(const json& root, const std::filesystem::path& path,
                                        JsonReader& reader);
// Returns nullptr after reporting problems (ann.cpp).
std::unique_ptr<ControlModel> load_ann(const json& root, const std::filesystem::path& path, JsonReader& reader);

// Parses JSON text; a syntax error throws InputError with file:line:column.
json parse_json_file(const std::filesystem::path& path);
// load_model without the boundary that names the file for library errors.
std::unique_ptr<ControlModel> load_model_json(const std::filesystem::path& path);

// Throws InputError naming the phone and segment if `entry` is null.
[[noreturn]] void missing_phone(const Phone& phone, std::size_t segment, std::string_view kind);

}  // namespace avsi::synth::detail
