// TOML configuration with source locations (see config.h); parsing by toml++.
#include "avsi/core/config.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "avsi/core/files.h"

namespace avsi {

namespace {

std::string quote(std::string_view s) { return fmt::format("\"{}\"", s); }

std::string join_quoted(const std::vector<std::string>& items) {
    std::string out;
    for (std::size_t i = 0; i < items.size(); ++i) {
        if (i > 0) out += i + 1 == items.size() ? (items.size() > 2 ? ", or " : " or ") : ", ";
        out += quote(items[i]);
    }
    return out;
}

std::string format_number(double v) {
    if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 1e15) return fmt::format("{:.0f}", v);
    return fmt::format("{}", v);
}

ConfigValue convert(const toml::node& node, const std::string& path, const std::string& name);

std::shared_ptr<ConfigSection> convert_table(const toml::table& table, const std::string& path,
                                             const std::string& name) {
    auto section = std::make_shared<ConfigSection>(path, name,
                                                   static_cast<int>(table.source().begin.line),
                                                   static_cast<int>(table.source().begin.column));
    section->set_present(true);
    // toml++ keeps keys sorted; restore file order so messages come in reading order.
    std::vector<std::pair<const toml::key*, const toml::node*>> entries;
    for (const auto& [key, node] : table) entries.emplace_back(&key, &node);
    std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
        const auto& sa = a.first->source().begin;
        const auto& sb = b.first->source().begin;
        return sa.line != sb.line ? sa.line < sb.line : sa.column < sb.column;
    });
    for (const auto& [key, node] : entries) {
        const std::string child_name =
            name.empty() ? std::string(key->str()) : name + "." + std::string(key->str());
        ConfigValue value = convert(*node, path, child_name);
        value.key_line = static_cast<int>(key->source().begin.line);
        value.key_column = static_cast<int>(key->source().begin.column);
        if (value.line == 0) {
            value.line = value.key_line;
            value.column = value.key_column;
        }
        section->set(std::string(key->str()), std::move(value));
    }
    return section;
}

ConfigValue convert(const toml::node& node, const std::string& path, const std::string& name) {
    ConfigValue v;
    v.line = static_cast<int>(node.source().begin.line);
    v.column = static_cast<int>(node.source().begin.column);
    if (auto s = node.as_string()) {
        v.type = ConfigValue::Type::String;
        v.string = s->get();
    } else if (auto i = node.as_integer()) {
        v.type = ConfigValue::Type::Integer;
        v.integer = i->get();
    } else if (auto f = node.as_floating_point()) {
        v.type = ConfigValue::Type::Float;
        v.number = f->get();
    } else if (auto b = node.as_boolean()) {
        v.type = ConfigValue::Type::Boolean;
        v.boolean = b->get();
    } else if (auto a = node.as_array()) {
        v.type = ConfigValue::Type::Array;
        int index = 0;
        for (const auto& item : *a) {
            v.items.push_back(convert(item, path, fmt::format("{}[{}]", name, index + 1)));
            ++index;
        }
    } else if (auto t = node.as_table()) {
        v.type = ConfigValue::Type::Table;
        v.table = convert_table(*t, path, name);
    } else {
        v.type = ConfigValue::Type::Date;
        std::ostringstream text;
        node.visit([&text](auto&& n) { text << n; });
        v.string = text.str();
    }
    return v;
}

}  // namespace

std::string ConfigValue::describe() const {
    switch (type) {
        case Type::String: return quote(string);
        case Type::Integer: return std::to_string(integer);
        case Type::Float: return format_number(number);
        case Type::Boolean: return boolean ? "true" : "false";
        case Type::Date: return "the date " + string;
        case Type::Array: return "an array";
        case Type::Table: return "a table";
    }
    return "?";
}

ConfigSection::ConfigSection(std::string path, std::string name, int line, int column)
    : m_path(std::move(path)), m_name(std::move(name)), m_line(line), m_column(column) {}

void ConfigSection::set(std::string key, ConfigValue value) {
    if (m_values.find(key) == m_values.end()) m_order.push_back(key);
    m_values[std::move(key)] = std::move(value);
}

bool ConfigSection::has(std::string_view key) const { return m_values.find(key) != m_values.end(); }

const ConfigValue* ConfigSection::find(std::string_view key) const {
    m_read.emplace(key);
    auto it = m_values.find(key);
    return it == m_values.end() ? nullptr : &it->second;
}

std::string ConfigSection::field(std::string_view key) const {
    return m_name.empty() ? std::string(key) : m_name + "." + std::string(key);
}

void ConfigSection::report(std::string_view key, const std::string& message,
                           DiagnosticList& problems) const {
    auto it = m_values.find(key);
    if (it != m_values.end())
        problems.add(m_path, it->second.line, it->second.column, field(key), message);
    else
        problems.add(m_path, m_line, m_column, field(key), message);
}

std::string ConfigSection::get_string(std::string_view key, const std::string& fallback,
                                      DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    if (!v) return fallback;
    if (v->type != ConfigValue::Type::String) {
        report(key, "expected a string, got " + v->describe(), problems);
        return fallback;
    }
    return v->string;
}

std::string ConfigSection::get_choice(std::string_view key, const std::vector<std::string>& choices,
                                      const std::string& fallback, DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    if (!v) return fallback;
    if (v->type != ConfigValue::Type::String ||
        std::find(choices.begin(), choices.end(), v->string) == choices.end()) {
        std::string message = "expected " + join_quoted(choices) + ", got " + v->describe();
        if (v->type == ConfigValue::Type::String) {
            const std::string hint = closest_match(v->string, choices);
            if (!hint.empty()) message += " (did you mean " + quote(hint) + "?)";
        }
        report(key, message, problems);
        return fallback;
    }
    return v->string;
}

long long ConfigSection::get_int(std::string_view key, long long fallback, long long min,
                                 long long max, DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    if (!v) return fallback;
    if (v->type != ConfigValue::Type::Integer || v->integer < min || v->integer > max) {
        report(key, fmt::format("expected an integer in [{}, {}], got {}", min, max, v->describe()),
               problems);
        return fallback;
    }
    return v->integer;
}

double ConfigSection::get_number(std::string_view key, double fallback, double min, double max,
                                 DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    if (!v) return fallback;
    double x = 0.0;
    bool ok = true;
    if (v->type == ConfigValue::Type::Integer)
        x = static_cast<double>(v->integer);
    else if (v->type == ConfigValue::Type::Float)
        x = v->number;
    else
        ok = false;
    if (!ok || !std::isfinite(x) || x < min || x > max) {
        report(key,
               fmt::format("expected a number in [{}, {}], got {}", format_number(min),
                           format_number(max), v->describe()),
               problems);
        return fallback;
    }
    return x;
}

bool ConfigSection::get_bool(std::string_view key, bool fallback, DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    if (!v) return fallback;
    if (v->type != ConfigValue::Type::Boolean) {
        report(key, "expected true or false, got " + v->describe(), problems);
        return fallback;
    }
    return v->boolean;
}

std::vector<std::string> ConfigSection::get_string_list(std::string_view key,
                                                        DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    std::vector<std::string> out;
    if (!v) return out;
    if (v->type != ConfigValue::Type::Array) {
        report(key, "expected an array of strings, got " + v->describe(), problems);
        return out;
    }
    for (std::size_t i = 0; i < v->items.size(); ++i) {
        const ConfigValue& item = v->items[i];
        if (item.type != ConfigValue::Type::String) {
            problems.add(m_path, item.line, item.column, fmt::format("{}[{}]", field(key), i + 1),
                         "expected a string, got " + item.describe());
            continue;
        }
        out.push_back(item.string);
    }
    return out;
}

const ConfigSection* ConfigSection::get_table(std::string_view key, DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    if (!v) return nullptr;
    if (v->type != ConfigValue::Type::Table) {
        report(key, "expected a table, got " + v->describe(), problems);
        return nullptr;
    }
    return v->table.get();
}

std::vector<const ConfigSection*> ConfigSection::get_table_array(std::string_view key,
                                                                 DiagnosticList& problems) const {
    const ConfigValue* v = find(key);
    std::vector<const ConfigSection*> out;
    if (!v) return out;
    if (v->type != ConfigValue::Type::Array) {
        report(key, "expected an array of tables ([[" + std::string(key) + "]]), got " + v->describe(),
               problems);
        return out;
    }
    for (std::size_t i = 0; i < v->items.size(); ++i) {
        const ConfigValue& item = v->items[i];
        if (item.type != ConfigValue::Type::Table) {
            problems.add(m_path, item.line, item.column, fmt::format("{}[{}]", field(key), i + 1),
                         "expected a table, got " + item.describe());
            continue;
        }
        out.push_back(item.table.get());
    }
    return out;
}

bool ConfigSection::require(std::string_view key, DiagnosticList& problems) const {
    m_read.emplace(key);
    if (has(key)) return true;
    problems.add(m_path, m_line, m_column, field(key), "missing required key");
    return false;
}

void ConfigSection::check_unknown_keys(const std::vector<std::string>& allowed,
                                       DiagnosticList& problems) const {
    for (const auto& key : m_order) {
        if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
        const ConfigValue& v = m_values.find(key)->second;
        std::string message = v.type == ConfigValue::Type::Table ? "unknown table" : "unknown key";
        const std::string hint = closest_match(key, allowed);
        if (!hint.empty()) message += " (did you mean " + quote(hint) + "?)";
        problems.add(m_path, v.key_line ? v.key_line : v.line, v.key_line ? v.key_column : v.column,
                     field(key), message);
    }
}

void ConfigSection::check_unknown_keys(DiagnosticList& problems) const {
    std::vector<std::string> allowed;
    for (const auto& key : m_read)
        if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) allowed.push_back(key);
    check_unknown_keys(allowed, problems);
}

ConfigSection parse_config(std::string_view text, const std::string& path) {
    toml::table root;
    try {
        root = toml::parse(text, path);
    } catch (const toml::parse_error& e) {
        const auto& where = e.source().begin;
        throw InputError(path, static_cast<int>(where.line), static_cast<int>(where.column), "",
                         "invalid TOML: " + std::string(e.description()));
    }
    auto section = convert_table(root, path, "");
    section->set_present(true);
    return *section;
}

ConfigSection read_config(const std::filesystem::path& path) {
    return parse_config(read_text_file(path), path.string());
}

}  // namespace avsi
