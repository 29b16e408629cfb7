// Marker exports as text (Qualisys TSV, OptiTrack Motive CSV), the choice of
// reader by extension, and the markers CSV avsi writes (markers.h).
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"
#include "avsi/learn/markers.h"

namespace avsi::learn {

std::size_t MarkerRecording::marker(const std::string& label) const {
    const auto it = std::find(labels.begin(), labels.end(), label);
    return it == labels.end() ? npos : static_cast<std::size_t>(it - labels.begin());
}

namespace {

constexpr std::size_t max_markers = 10000;
constexpr double max_text_rate_hz = 1e6;

const std::string* field_at(const CsvRow& row, std::size_t i) {
    return i < row.fields.size() ? &row.fields[i] : nullptr;
}

double require_rate(const std::string& text, const std::string& file, int line, const std::string& field) {
    const auto v = parse_double(trim(text));
    if (!v || *v <= 0.0 || *v > max_text_rate_hz)
        throw InputError(file, line, 0, field, fmt::format("expected a frame rate in (0, {}] Hz, got \"{}\"", max_text_rate_hz, text));
    return *v;
}

// Parses one marker's x, y, z cells at `col` of a row into `p` (mm); empty
// cells (all three) leave the dropout; `zero_is_gap` treats 0 0 0 as one.
void read_xyz(const CsvRow& row, std::size_t col, const std::string& file, const std::string& label, double mm,
              bool zero_is_gap, double* p) {
    std::string cells[3];
    int empty = 0;
    for (int k = 0; k < 3; ++k) {
        const std::string* f = field_at(row, col + k);
        cells[k] = f ? trim(*f) : std::string();
        empty += cells[k].empty() ? 1 : 0;
    }
    if (empty == 3) return;
    double v[3];
    for (int k = 0; k < 3; ++k) {
        const auto d = cells[k].empty() ? std::nullopt : parse_double(cells[k]);
        if (!d || std::abs(*d * mm) > 1e7)
            throw InputError(file, row.line, static_cast<int>(col + k + 1), fmt::format("{} {}", label, "XYZ"[k]),
                             fmt::format("expected a coordinate (finite, within 10 km), got \"{}\"", cells[k]));
        v[k] = *d * mm;
    }
    if (zero_is_gap && v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0) return;
    std::copy(v, v + 3, p);
}

std::vector<CsvRow> read_rows(const std::filesystem::path& path, char delimiter) {
    CsvOptions options;
    options.delimiter = delimiter;
    options.has_header = false;
    options.skip_comments = false;
    return parse_csv(read_text_file(path), path.string(), options).rows;
}

void check_labels(const std::vector<std::string>& labels, const std::string& file, int line, const std::string& field) {
    if (labels.empty()) throw InputError(file, line, 0, field, "no markers");
    if (labels.size() > max_markers)
        throw InputError(file, line, 0, field, fmt::format("{} markers, at most {} are read", labels.size(), max_markers));
    for (std::size_t i = 0; i < labels.size(); ++i)
        for (std::size_t j = 0; j < i; ++j)
            if (labels[i] == labels[j])
                throw InputError(file, line, 0, field, fmt::format("marker \"{}\" appears twice", labels[i]));
}

}  // namespace

MarkerRecording read_qualisys_tsv(const std::filesystem::path& path) {
    const std::string file = path.string();
    const std::vector<CsvRow> rows = read_rows(path, '\t');
    std::map<std::string, const CsvRow*> header;
    std::size_t r = 0;
    for (; r < rows.size(); ++r) {
        const std::string key = rows[r].fields.empty() ? "" : trim(rows[r].fields[0]);
        if (key.empty() || key == "Frame" || parse_double(key)) break;
        header[key] = &rows[r];
    }
    if (!header.count("MARKER_NAMES") || !header.count("FREQUENCY"))
        throw InputError(file, rows.empty() ? 1 : rows[std::min(r, rows.size() - 1)].line, 0,
                         header.count("FREQUENCY") ? "MARKER_NAMES" : "FREQUENCY",
                         "not in the header (a Qualisys TSV export has FREQUENCY and MARKER_NAMES lines)");
    const CsvRow& names = *header["MARKER_NAMES"];
    MarkerRecording out;
    for (std::size_t i = 1; i < names.fields.size(); ++i)
        if (!trim(names.fields[i]).empty()) out.labels.push_back(trim(names.fields[i]));
    check_labels(out.labels, file, names.line, "MARKER_NAMES");
    const CsvRow& freq = *header["FREQUENCY"];
    out.rate_hz = require_rate(freq.fields.size() > 1 ? freq.fields[1] : "", file, freq.line, "FREQUENCY");
    if (header.count("NO_OF_MARKERS")) {
        const CsvRow& n = *header["NO_OF_MARKERS"];
        const auto v = n.fields.size() > 1 ? parse_int(trim(n.fields[1])) : std::nullopt;
        if (!v || *v != static_cast<long long>(out.labels.size()))
            throw InputError(file, n.line, 0, "NO_OF_MARKERS",
                             fmt::format("expected {} (the MARKER_NAMES), got \"{}\"", out.labels.size(),
                                         n.fields.size() > 1 ? n.fields[1] : ""));
    }
    const bool columns = r < rows.size() && !rows[r].fields.empty() && trim(rows[r].fields[0]) == "Frame";
    const std::size_t first_col = columns ? 2 : 0;
    if (columns) ++r;
    const std::size_t n = out.labels.size();
    out.frames = rows.size() - r;
    out.xyz.assign(out.frames * n * 3, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t f = 0; f < out.frames; ++f) {
        const CsvRow& row = rows[r + f];
        std::size_t used = row.fields.size();
        while (used > first_col + 3 * n && trim(row.fields[used - 1]).empty()) --used;
        if (used != first_col + 3 * n)
            throw InputError(file, row.line, 0, "frame",
                             fmt::format("expected {} fields ({}x, y, z of {} markers), got {}", first_col + 3 * n,
                                         columns ? "frame, time, " : "", n, used));
        if (columns && f == 0) {
            const auto t = parse_double(trim(row.fields[1]));
            if (!t) throw InputError(file, row.line, 2, "Time", fmt::format("expected a time in s, got \"{}\"", row.fields[1]));
            out.start_s = *t;
        }
        for (std::size_t m = 0; m < n; ++m)
            read_xyz(row, first_col + 3 * m, file, out.labels[m], 1.0, true, out.point(f, m));
    }
    if (header.count("NO_OF_FRAMES")) {
        const CsvRow& h = *header["NO_OF_FRAMES"];
        const auto v = h.fields.size() > 1 ? parse_int(trim(h.fields[1])) : std::nullopt;
        if (!v || *v != static_cast<long long>(out.frames))
            throw InputError(file, h.line, 0, "NO_OF_FRAMES",
                             fmt::format("the file has {} frame rows, the header says \"{}\"", out.frames,
                                         h.fields.size() > 1 ? h.fields[1] : ""));
    }
    return out;
}

namespace {

// The first line's key,value pairs of a Motive export.
std::map<std::string, std::string> motive_settings(const CsvRow& row) {
    std::map<std::string, std::string> out;
    for (std::size_t i = 0; i + 1 < row.fields.size(); i += 2) out[trim(row.fields[i])] = trim(row.fields[i + 1]);
    return out;
}

double motive_mm(const std::map<std::string, std::string>& settings, const std::string& file, int line) {
    const auto it = settings.find("Length Units");
    if (it == settings.end())
        throw InputError(file, line, 0, "Length Units",
                         "not in the first line (export from Motive 1.10 or later, which writes the unit)");
    if (it->second == "Millimeters") return 1.0;
    if (it->second == "Centimeters") return 10.0;
    if (it->second == "Meters") return 1000.0;
    throw InputError(file, line, 0, "Length Units",
                     fmt::format("expected Millimeters, Centimeters or Meters, got \"{}\"", it->second));
}

// The row whose first cell is `key` (after the settings line), or fail.
std::size_t motive_row(const std::vector<CsvRow>& rows, const std::string& key, const std::string& file) {
    for (std::size_t i = 1; i < rows.size() && i < 12; ++i)
        if (!rows[i].fields.empty() && trim(rows[i].fields[0]) == key) return i;
    throw InputError(file, rows.size() > 1 ? rows[1].line : 1, 0, key,
                     fmt::format("no \"{}\" row in the header (a Motive CSV export has Type, Name, ID and Frame rows)", key));
}

}  // namespace

MarkerRecording read_motive_csv(const std::filesystem::path& path) {
    const std::string file = path.string();
    const std::vector<CsvRow> rows = read_rows(path, ',');
    if (rows.empty() || rows[0].fields.empty() || trim(rows[0].fields[0]) != "Format Version")
        throw InputError(file, 1, 1, "Format Version", "a Motive CSV export starts with \"Format Version,…\"");
    const auto settings = motive_settings(rows[0]);
    const double mm = motive_mm(settings, file, rows[0].line);
    MarkerRecording out;
    const auto rate = settings.find("Export Frame Rate");
    out.rate_hz = require_rate(rate == settings.end() ? "" : rate->second, file, rows[0].line, "Export Frame Rate");
    const CsvRow& type = rows[motive_row(rows, "Type", file)];
    const CsvRow& name = rows[motive_row(rows, "Name", file)];
    const std::size_t frame_row = motive_row(rows, "Frame", file);
    const CsvRow& axis = rows[frame_row];
    const CsvRow& property = rows[frame_row - 1];
    std::vector<std::size_t> columns;  // the X column of each marker
    for (std::size_t c = 2; c + 2 < axis.fields.size(); ++c) {
        auto cell = [&](const CsvRow& row, std::size_t i) { return i < row.fields.size() ? trim(row.fields[i]) : std::string(); };
        if (cell(type, c) != "Marker" || cell(property, c) != "Position" || cell(axis, c) != "X") continue;
        if (cell(axis, c + 1) != "Y" || cell(axis, c + 2) != "Z" || cell(name, c + 1) != cell(name, c))
            throw InputError(file, axis.line, static_cast<int>(c + 1), cell(name, c),
                             "expected the marker's X, Y and Z position columns side by side");
        columns.push_back(c);
        out.labels.push_back(cell(name, c));
    }
    check_labels(out.labels, file, name.line, "Name");
    const std::size_t n = out.labels.size();
    out.frames = rows.size() - frame_row - 1;
    out.xyz.assign(out.frames * n * 3, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t f = 0; f < out.frames; ++f) {
        const CsvRow& row = rows[frame_row + 1 + f];
        if (row.fields.size() > axis.fields.size() || row.fields.size() < 2)
            throw InputError(file, row.line, 0, "frame",
                             fmt::format("expected at most {} fields as in the Frame row, got {}", axis.fields.size(),
                                         row.fields.size()));
        if (f == 0) {
            const auto t = parse_double(trim(row.fields[1]));
            if (!t) throw InputError(file, row.line, 2, "Time", fmt::format("expected a time in s, got \"{}\"", row.fields[1]));
            out.start_s = *t;
        }
        for (std::size_t m = 0; m < n; ++m) read_xyz(row, columns[m], file, out.labels[m], mm, false, out.point(f, m));
    }
    return out;
}

MarkerRecording read_marker_file(const std::filesystem::path& path) {
    const std::string ext = ascii_lower(path.extension().string());
    if (ext == ".c3d") return read_c3d(path);
    if (ext == ".tsv") return read_qualisys_tsv(path);
    if (ext == ".csv") return read_motive_csv(path);
    throw InputError(path, fmt::format("unsupported marker file extension '{}'; supported are '.c3d' (C3D), '.tsv' "
                                       "(Qualisys TSV) and '.csv' (OptiTrack Motive CSV)", path.extension().string()));
}

void write_markers_csv(const std::filesystem::path& path, const MarkerRecording& recording) {
    std::string out = "time_s";
    for (const auto& l : recording.labels)
        for (const char* axis : {"_x", "_y", "_z"}) out += "," + csv_escape(l + axis);
    out += '\n';
    for (std::size_t f = 0; f < recording.frames; ++f) {
        out += fmt::format("{:.6f}", recording.time_s(f));
        for (std::size_t m = 0; m < recording.marker_count(); ++m) {
            const double* p = recording.point(f, m);
            if (recording.seen(f, m)) out += fmt::format(",{:.3f},{:.3f},{:.3f}", p[0], p[1], p[2]);
            else out += ",,,";
        }
        out += '\n';
    }
    write_text_file(path, out);
}

}  // namespace avsi::learn
