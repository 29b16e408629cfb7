// CSV reading and writing (RFC 4180: comma-separated, double-quoted fields
// with "" escapes, fields may span lines), keeping each row's line number so
// errors can say file:line. Also reads tab-separated files.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace avsi {

struct CsvRow {
    int line = 0;  // 1-based line where the row starts
    std::vector<std::string> fields;
};

struct CsvTable {
    std::string path;
    std::vector<std::string> header;
    std::vector<CsvRow> rows;

    // Index of a header column, or nullopt.
    std::optional<std::size_t> column(std::string_view name) const;
    // Index of a required column; throws InputError naming the file, the
    // missing column and the columns present (with "did you mean").
    std::size_t require_column(std::string_view name) const;
};

struct CsvOptions {
    char delimiter = ',';
    bool has_header = true;
    bool skip_comments = true;  // lines starting with '#'
};

// Parses CSV text; `path` is only used in error messages.
CsvTable parse_csv(std::string_view text, const std::string& path, const CsvOptions& options = {});
// Reads a CSV file (UTF-8, BOM allowed). Throws InputError with file:line.
CsvTable read_csv(const std::filesystem::path& path, const CsvOptions& options = {});

// Quotes a field if it holds the delimiter, a quote or a line break.
std::string csv_escape(std::string_view field, char delimiter = ',');
// One CSV line (with trailing '\n') from fields.
std::string csv_line(const std::vector<std::string>& fields, char delimiter = ',');

// Number parsing for data files: the whole field must be a finite number.
std::optional<double> parse_double(std::string_view text);
std::optional<long long> parse_int(std::string_view text);

}  // namespace avsi
