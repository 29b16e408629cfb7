// Generic access to TOML configuration with source locations. A ConfigSection
// is one table of a TOML file (e.g. [vocoder], or the 3rd [[condition]]):
// key → value, each value remembering its line and column, with typed getters
// that report problems as Diagnostics in the one compiler-style format
//   protocols/study.toml:17:9: error: vocoder.bands: expected an integer in [1, 32], got "three"
// so a module can validate its own section, collect every problem, and fail
// once. toml++ does the parsing; no toml++ type appears in this header.
//
// Usage:
//   avsi::DiagnosticList problems;
//   const avsi::ConfigSection& v = protocol.vocoder;
//   int bands = int(v.get_int("bands", 3, 1, 32, problems));
//   v.check_unknown_keys(problems);   // keys not read above → "did you mean"
//   problems.throw_if_any();
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/error.h"

namespace avsi {

class ConfigSection;

// One TOML value with where it was written.
struct ConfigValue {
    enum class Type { String, Integer, Float, Boolean, Date, Array, Table };
    Type type = Type::String;
    std::string string;        // Type::String (and the text of a Date)
    long long integer = 0;     // Type::Integer
    double number = 0.0;       // Type::Float
    bool boolean = false;      // Type::Boolean
    std::vector<ConfigValue> items;           // Type::Array
    std::shared_ptr<ConfigSection> table;     // Type::Table (also each table of an array of tables)
    int line = 0;        // where the value starts
    int column = 0;
    int key_line = 0;    // where its key starts (0 for array items)
    int key_column = 0;

    // How the value reads in an error message: "three" (quoted), 3, 2.5, true,
    // an array, a table.
    std::string describe() const;
};

// One table of a configuration file.
class ConfigSection {
public:
    ConfigSection() = default;
    // `path` is the file (for messages); `name` the dotted name used as the
    // field prefix ("vocoder", "condition[2]"); line/column where the table starts.
    ConfigSection(std::string path, std::string name, int line, int column);

    const std::string& path() const { return m_path; }
    const std::string& name() const { return m_name; }
    int line() const { return m_line; }
    int column() const { return m_column; }
    // False for a section that was not in the file (an empty default).
    bool present() const { return m_present; }
    void set_present(bool present) { m_present = present; }

    void set(std::string key, ConfigValue value);
    bool has(std::string_view key) const;
    // The value, or nullptr; marks the key as read.
    const ConfigValue* find(std::string_view key) const;
    // Keys in file order.
    const std::vector<std::string>& keys() const { return m_order; }
    // "name.key" (or "key" for the root).
    std::string field(std::string_view key) const;

    // Typed getters. Each marks the key as read. When the key is absent they
    // return the default; when it has the wrong type or is out of range they
    // add "expected …, got …" at the value's location and return the default.
    std::string get_string(std::string_view key, const std::string& fallback,
                           DiagnosticList& problems) const;
    // One of `choices`; a near miss gets "did you mean".
    std::string get_choice(std::string_view key, const std::vector<std::string>& choices,
                           const std::string& fallback, DiagnosticList& problems) const;
    long long get_int(std::string_view key, long long fallback, long long min, long long max,
                      DiagnosticList& problems) const;
    // Accepts integers and floats.
    double get_number(std::string_view key, double fallback, double min, double max,
                      DiagnosticList& problems) const;
    bool get_bool(std::string_view key, bool fallback, DiagnosticList& problems) const;
    // An array of strings (absent → empty).
    std::vector<std::string> get_string_list(std::string_view key, DiagnosticList& problems) const;
    // A nested table (absent → nullopt; wrong type → diagnostic and nullopt).
    const ConfigSection* get_table(std::string_view key, DiagnosticList& problems) const;
    // An array of tables, e.g. [[condition]] (absent → empty).
    std::vector<const ConfigSection*> get_table_array(std::string_view key,
                                                      DiagnosticList& problems) const;

    // Reports a missing required key at the section's location:
    // "file:line:col: error: design.lists: missing required key". Returns
    // whether the key is present.
    bool require(std::string_view key, DiagnosticList& problems) const;

    // Adds a diagnostic at the key's value (or at the section if absent).
    void report(std::string_view key, const std::string& message, DiagnosticList& problems) const;

    // Every key not in `allowed` is reported as "unknown key" with "did you mean".
    void check_unknown_keys(const std::vector<std::string>& allowed, DiagnosticList& problems) const;
    // Every key not read so far through a getter is reported as unknown, with
    // "did you mean" among the keys that were read.
    void check_unknown_keys(DiagnosticList& problems) const;

private:
    std::string m_path;
    std::string m_name;
    int m_line = 0;
    int m_column = 0;
    bool m_present = false;
    std::map<std::string, ConfigValue, std::less<>> m_values;
    std::vector<std::string> m_order;
    mutable std::set<std::string, std::less<>> m_read;
};

// Parses TOML text into the root section; `path` is used in messages.
// A TOML syntax error throws InputError with file:line:col.
ConfigSection parse_config(std::string_view text, const std::string& path);
// Reads and parses a TOML file. Throws InputError if it cannot be read.
ConfigSection read_config(const std::filesystem::path& path);

}  // namespace avsi
