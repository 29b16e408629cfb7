#include "avsi/core/csv.h"

#include <charconv>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"

namespace avsi {

std::optional<std::size_t> CsvTable::column(std::string_view name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
        if (header[i] == name) return i;
    return std::nullopt;
}

std::size_t CsvTable::require_column(std::string_view name) const {
    if (auto c = column(name)) return *c;
    std::string present;
    for (const auto& h : header) present += (present.empty() ? "" : ", ") + h;
    std::string hint;
    const std::string close = closest_match(std::string(name), header);
    if (!close.empty()) hint = fmt::format(" (did you mean '{}'?)", close);
    throw InputError(path, 1, 0, "header",
                     fmt::format("expected a column '{}', got columns: {}{}", name, present, hint));
}

CsvTable parse_csv(std::string_view text, const std::string& path, const CsvOptions& options) {
    if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    CsvTable table;
    table.path = path;
    std::vector<CsvRow> rows;
    std::size_t i = 0;
    int line = 1;
    while (i < text.size()) {
        // Skip blank lines and comments.
        if (text[i] == '\n' || text[i] == '\r') {
            if (text[i] == '\n') ++line;
            ++i;
            continue;
        }
        if (options.skip_comments && text[i] == '#') {
            while (i < text.size() && text[i] != '\n') ++i;
            continue;
        }
        CsvRow row;
        row.line = line;
        std::string field;
        bool in_quotes = false;
        bool quoted = false;
        int quote_line = line;
        for (;;) {
            if (i >= text.size()) {
                if (in_quotes)
                    throw InputError(path, quote_line, 0, "",
                                     "expected a closing '\"' for the quoted field, got end of file");
                row.fields.push_back(std::move(field));
                break;
            }
            const char c = text[i];
            if (in_quotes) {
                if (c == '"') {
                    if (i + 1 < text.size() && text[i + 1] == '"') {
                        field += '"';
                        i += 2;
                    } else {
                        in_quotes = false;
                        ++i;
                    }
                } else {
                    if (c == '\n') ++line;
                    field += c;
                    ++i;
                }
                continue;
            }
            if (c == '"' && field.empty() && !quoted) {
                in_quotes = quoted = true;
                quote_line = line;
                ++i;
            } else if (c == options.delimiter) {
                row.fields.push_back(std::move(field));
                field.clear();
                quoted = false;
                ++i;
            } else if (c == '\r' || c == '\n') {
                row.fields.push_back(std::move(field));
                if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
                ++i;
                ++line;
                break;
            } else {
                field += c;
                ++i;
            }
        }
        rows.push_back(std::move(row));
    }
    if (options.has_header) {
        if (rows.empty()) throw InputError(path, 1, 0, "header", "expected a header line, got an empty file");
        table.header = std::move(rows.front().fields);
        for (auto& h : table.header) {
            while (!h.empty() && (h.back() == ' ' || h.back() == '\t')) h.pop_back();
            while (!h.empty() && (h.front() == ' ' || h.front() == '\t')) h.erase(h.begin());
        }
        rows.erase(rows.begin());
        for (const auto& row : rows)
            if (row.fields.size() != table.header.size())
                throw InputError(path, row.line, 0, "",
                                 fmt::format("expected {} fields as in the header, got {}",
                                             table.header.size(), row.fields.size()));
    }
    table.rows = std::move(rows);
    return table;
}

CsvTable read_csv(const std::filesystem::path& path, const CsvOptions& options) {
    return parse_csv(read_text_file(path), path.string(), options);
}

std::string csv_escape(std::string_view field, char delimiter) {
    if (field.find_first_of(std::string{delimiter, '"', '\n', '\r'}) == std::string_view::npos)
        return std::string(field);
    std::string out = "\"";
    for (char c : field) {
        if (c == '"') out += '"';
        out += c;
    }
    out += '"';
    return out;
}

std::string csv_line(const std::vector<std::string>& fields, char delimiter) {
    std::string out;
    for (std::size_t i = 0; i < fields.size(); ++i) {
        if (i) out += delimiter;
        out += csv_escape(fields[i], delimiter);
    }
    out += '\n';
    return out;
}

std::optional<double> parse_double(std::string_view text) {
    text = trim_view(text);
    if (text.empty()) return std::nullopt;
    if (text.front() == '+') text.remove_prefix(1);
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc{} || ptr != text.data() + text.size() || !std::isfinite(value))
        return std::nullopt;
    return value;
}

std::optional<long long> parse_int(std::string_view text) {
    text = trim_view(text);
    if (text.empty()) return std::nullopt;
    if (text.front() == '+') text.remove_prefix(1);
    long long value = 0;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc{} || ptr != text.data() + text.size()) return std::nullopt;
    return value;
}

}  // namespace avsi
