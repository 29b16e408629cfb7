// Shard files of the simulations (see simulation_shards.h).
#include "simulation_shards.h"

#include <fstream>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"

namespace avsi::analysis::detail {

namespace {

// Longer lines than any a shard file holds (its settings line included).
constexpr std::size_t max_line_bytes = 64 << 10;

std::vector<std::string_view> split_fields(std::string_view line) {
    std::vector<std::string_view> fields;
    std::size_t start = 0;
    while (true) {
        const std::size_t comma = line.find(',', start);
        fields.push_back(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
        if (comma == std::string_view::npos) break;
        start = comma + 1;
    }
    return fields;
}

// The settings that differ between a shard's and this run's, as
// "name X (this run: Y)".
std::string differing_settings(const nlohmann::json& theirs, const nlohmann::json& ours) {
    std::string out;
    for (const auto& [key, value] : ours.items()) {
        const nlohmann::json other = theirs.is_object() && theirs.contains(key) ? theirs[key] : nlohmann::json();
        if (other != value)
            out += fmt::format("{}{} {} (this run: {})", out.empty() ? "" : ", ", key, excerpt(other.dump(), 80),
                               excerpt(value.dump(), 80));
    }
    if (theirs.is_object())
        for (const auto& [key, value] : theirs.items())
            if (!ours.contains(key)) out += fmt::format("{}{} {} (not a setting of this run)", out.empty() ? "" : ", ", key,
                                                        excerpt(value.dump(), 80));
    return out;
}

// Reads one line (without its newline) into `line`; false at the end.
bool read_line(std::istream& in, std::string& line, const std::string& file, int number) {
    line.clear();
    char c = 0;
    bool any = false;
    while (in.get(c)) {
        any = true;
        if (c == '\n') {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            return true;
        }
        if (line.size() >= max_line_bytes)
            throw InputError(file, number, 0, "", fmt::format("line longer than {} bytes: not a shard file", max_line_bytes));
        line += c;
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return any;
}

// The value after "# <prefix> " on a header line, or fails naming what was expected.
std::string header_value(const std::string& line, const std::string& prefix, const std::string& file, int number) {
    const std::string head = "# " + prefix + " ";
    if (line.rfind(head, 0) != 0)
        throw InputError(file, number, 0, "header",
                         fmt::format("expected \"{}…\", got \"{}\": not a shard file of this command", head,
                                     excerpt(line)));
    return line.substr(head.size());
}

// The column names line, without its newline.
std::string column_line(const ShardKind& kind) {
    std::string line = csv_line(kind.columns);
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    return line;
}

}  // namespace

std::filesystem::path shard_file_path(const std::filesystem::path& out_dir, const ShardKind& kind, ShardSpec shard) {
    return out_dir / (kind.stem + "." + shard.stem() + ".csv");
}

long long ShardRow::integer(std::size_t column) const {
    const auto v = parse_int(fields[column]);
    if (!v) fail(column, fmt::format("expected an integer, got \"{}\"", excerpt(fields[column])));
    return *v;
}

double ShardRow::number(std::size_t column) const {
    const auto v = parse_double(fields[column]);
    if (!v) fail(column, fmt::format("expected a finite number, got \"{}\"", excerpt(fields[column])));
    return *v;
}

void write_shard_file(const std::filesystem::path& out_dir, const ShardKind& kind, ShardSpec shard,
                      const nlohmann::json& settings, const std::string& rows) {
    std::string text = fmt::format("# {} {}\n# avsi {}\n# settings {}\n{}\n", kind.format, shard.text(),
                                   avsi_version(), settings.dump(), column_line(kind));
    text += rows;
    write_text_file(shard_file_path(out_dir, kind, shard), text);
}

std::size_t read_shard_files(
    const std::filesystem::path& out_dir, const ShardKind& kind, const nlohmann::json& settings,
    const std::function<void(ShardSpec shard, const ShardRow& row)>& row,
    const std::function<void(ShardSpec shard, const std::function<void(const std::string&)>& fail)>& end) {
    const ShardFiles files = find_shard_files(out_dir, kind.stem + ".", ".csv", kind.rerun);
    const std::string columns = column_line(kind);
    for (std::size_t k = 0; k < files.count; ++k) {
        const ShardSpec shard{k, files.count};
        const std::string file = files.files[k].string();
        std::ifstream in(files.files[k], std::ios::binary);
        if (!in) throw InputError(files.files[k], "cannot open the shard file");
        std::string line;
        int number = 0;
        const auto next = [&](const std::string& what) {
            if (!read_line(in, line, file, ++number))
                throw InputError(file, number, 0, "header", "the file ends before its " + what + ": not a shard file");
        };
        next("first line");
        const std::string claimed = header_value(line, kind.format, file, number);
        if (claimed != shard.text())
            throw InputError(file, number, 0, "shard",
                             fmt::format("claims to be shard {} but is named {}: two shards would claim the same "
                                         "replicates; remove it and rerun {} --shard {}",
                                         excerpt(claimed), files.files[k].filename().string(), kind.rerun, shard.text()));
        next("avsi version");
        const std::string version = header_value(line, "avsi", file, number);
        if (version != avsi_version())
            throw InputError(file, number, 0, "avsi",
                             fmt::format("stale: made by avsi {}, this is avsi {}; rerun {} --shard {}", excerpt(version),
                                         avsi_version(), kind.rerun, shard.text()));
        next("settings");
        nlohmann::json theirs;
        try {
            theirs = parse_json(header_value(line, "settings", file, number), file);
        } catch (const InputError& e) {  // at the file's line, not the JSON text's
            throw InputError(file, number, 0, "settings", e.first().message);
        }
        if (theirs != settings)
            throw InputError(file, number, 0, "settings",
                             fmt::format("foreign: made with other settings: {}; merge with the settings the shards "
                                         "were run with, or rerun {} --shard {} with these",
                                         differing_settings(theirs, settings), kind.rerun, shard.text()));
        next("column names");
        if (line != columns)
            throw InputError(file, number, 0, "columns",
                             fmt::format("expected \"{}\", got \"{}\"", columns, excerpt(line)));
        ShardRow r;
        while (read_line(in, line, file, ++number)) {
            r.fields = split_fields(line);
            r.line = number;
            r.fail = [&](std::size_t column, const std::string& message) {
                throw InputError(file, number, 0, column < kind.columns.size() ? kind.columns[column] : "row", message);
            };
            if (r.fields.size() != kind.columns.size())
                r.fail(kind.columns.size(), fmt::format("expected {} fields, got {}", kind.columns.size(), r.fields.size()));
            row(shard, r);
        }
        // At the last line read (the loop stopped after it).
        end(shard, [&](const std::string& message) { throw InputError(file, number - 1, 0, "rows", message); });
    }
    return files.count;
}

}  // namespace avsi::analysis::detail
