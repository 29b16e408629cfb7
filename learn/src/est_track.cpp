// EST track files (Edinburgh Speech Tools), as MOCHA-TIMIT and mngu0 ship
// EMA data, and sensor CSV. See est_track.h for the layout.
#include "avsi/learn/est_track.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "avsi/core/checks.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"
#include "avsi/learn/haskins_mat.h"

namespace avsi::learn {

std::size_t EstTrack::channel(const std::string& name) const {
    const auto it = std::find(channels.begin(), channels.end(), name);
    return it == channels.end() ? npos : static_cast<std::size_t>(it - channels.begin());
}

namespace {

float swap_float(float v) {
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    u = ((u & 0xff) << 24) | ((u & 0xff00) << 8) | ((u >> 8) & 0xff00) | (u >> 24);
    std::memcpy(&v, &u, 4);
    return v;
}

bool parse_bool(const std::string& v, bool& out) {
    const std::string l = ascii_lower(v);
    if (l == "true" || l == "1" || l == "yes") {
        out = true;
        return true;
    }
    if (l == "false" || l == "0" || l == "no") {
        out = false;
        return true;
    }
    return false;
}

// The largest magnitude a track value may have: EMA coordinates are
// millimetres (a head is ~200 mm), other channels (F0 in Hz, energies)
// stay far below 10⁶; 10³⁸ is a corrupt file, not a measurement.
constexpr double k_max_track_value = 1e6;
// The most channels a track may declare (MOCHA has 14–22, mngu0 36).
constexpr std::size_t k_max_channels = 10000;

// The binary frames after the header at `pos`: float32 time, break flag
// (with breaks) and channel values, byte-swapped when `swap`.
void read_binary_frames(const std::string& bytes, std::size_t pos, const std::string& file, std::size_t frames,
                        std::size_t nch, bool breaks, bool swap, EstTrack& track) {
    const std::size_t stride = 1 + (breaks ? 1 : 0) + nch;
    const std::size_t need = frames * stride * 4;
    const std::size_t have = bytes.size() - pos;
    if (have != need)
        throw InputError(file, 0, 0, "data",
                         fmt::format("expected {} bytes of float32 frames ({} frames × {} values), got {}",
                                     need, frames, stride, have));
    std::vector<float> row(stride);
    for (std::size_t k = 0; k < frames; ++k) {
        std::memcpy(row.data(), bytes.data() + pos + k * stride * 4, stride * 4);
        if (swap)
            for (auto& v : row) v = swap_float(v);
        const bool present = breaks ? row[1] != 0.0f : true;
        require_time_s(row[0], at(file, 0, 0, fmt::format("frame {} time", k + 1)));
        for (std::size_t i = breaks ? 2 : 1; present && i < stride; ++i)
            require_in_range(row[i], -k_max_track_value, k_max_track_value,
                             at(file, 0, 0, fmt::format("frame {} {}", k + 1, track.channels[i - (breaks ? 2 : 1)])));
        track.times_s.push_back(row[0]);
        track.present.push_back(breaks ? row[1] != 0.0f : true);
        track.values.emplace_back(row.begin() + (breaks ? 2 : 1), row.end());
    }
}

// The ASCII frames after the header at `pos` (line `line_no`), one per line;
// lines starting with `comment` are skipped.
void read_ascii_frames(const std::string& bytes, std::size_t pos, int line_no, const std::string& file,
                       const std::string& comment, std::size_t frames, std::size_t nch, bool breaks, EstTrack& track) {
    while (pos < bytes.size() && track.times_s.size() <= frames) {
        const std::size_t eol = bytes.find('\n', pos);
        const std::string line = trim(
            std::string_view(bytes).substr(pos, (eol == std::string::npos ? bytes.size() : eol) - pos));
        pos = eol == std::string::npos ? bytes.size() : eol + 1;
        ++line_no;
        if (line.empty() || (!comment.empty() && line.rfind(comment, 0) == 0)) continue;
        std::istringstream in(line);
        std::vector<std::string> fields;
        for (std::string f; in >> f;) fields.push_back(f);
        const std::size_t want = 1 + (breaks ? 1 : 0) + nch;
        if (fields.size() != want)
            throw InputError(file, line_no, 1, "frame",
                             fmt::format("expected {} values (time{}, {} channels), got {}", want,
                                         breaks ? ", break flag" : "", nch, fields.size()));
        std::vector<float> values;
        for (std::size_t i = 0; i < fields.size(); ++i) {
            const auto v = parse_double(fields[i]);
            const Diagnostic where = at(file, line_no, 0, i == 0 ? "time" : fmt::format("value {}", i + 1));
            if (!v)
                throw InputError(file, line_no, 0, where.field,
                                 fmt::format("expected a number, got \"{}\"", fields[i]));
            if (i == 0) require_time_s(*v, where);
            else require_in_range(*v, -k_max_track_value, k_max_track_value, where);
            values.push_back(static_cast<float>(*v));
        }
        if (track.times_s.size() == frames)
            throw InputError(file, line_no, 1, "NumFrames",
                             fmt::format("more frames than the header's {}", frames));
        track.times_s.push_back(values[0]);
        track.present.push_back(breaks ? values[1] != 0.0f : true);
        track.values.emplace_back(values.begin() + (breaks ? 2 : 1), values.end());
    }
    if (track.times_s.size() != frames)
        throw InputError(file, line_no, 0, "NumFrames",
                         fmt::format("expected {} frames, got {}", frames, track.times_s.size()));
}

}  // namespace

EstTrack read_est_track(const std::filesystem::path& path) {
    const std::string bytes = read_text_file(path);
    const std::string file = path.string();

    // Header: "key value" lines up to EST_Header_End.
    std::size_t pos = 0;
    int line_no = 0;
    std::map<std::string, std::pair<std::string, int>> header;  // lower-case key → value, line
    std::map<std::size_t, std::string> channel_names;
    bool ended = false;
    while (pos < bytes.size()) {
        const std::size_t eol = bytes.find('\n', pos);
        const std::string line =
            trim(std::string_view(bytes).substr(pos, (eol == std::string::npos ? bytes.size() : eol) - pos));
        pos = eol == std::string::npos ? bytes.size() : eol + 1;
        ++line_no;
        if (line_no == 1) {
            if (line != "EST_File Track")
                throw InputError(file, 1, 1, "header",
                                 fmt::format("expected \"EST_File Track\", got \"{}\"", line.substr(0, 40)));
            continue;
        }
        if (line.empty()) continue;
        if (line == "EST_Header_End") {
            ended = true;
            break;
        }
        const auto space = line.find_first_of(" \t");
        const std::string key = line.substr(0, space);
        const std::string value = space == std::string::npos ? "" : trim(line.substr(space));
        const std::string lkey = ascii_lower(key);
        if (lkey.rfind("channel_", 0) == 0) {
            const auto n = parse_int(lkey.substr(8));
            if (!n || *n < 0)
                throw InputError(file, line_no, 1, key, "expected channel_<index>, got a bad index");
            channel_names[static_cast<std::size_t>(*n)] = value;
        } else {
            header[lkey] = {value, line_no};
        }
    }
    if (!ended) throw InputError(file, line_no, 0, "header", "no EST_Header_End line");

    auto require = [&](const std::string& key) -> std::pair<std::string, int> {
        const auto it = header.find(ascii_lower(key));
        if (it == header.end())
            throw InputError(file, 0, 0, key, "required header field is missing");
        return it->second;
    };
    // A declared count, at most `limit` and at most what the data after the
    // header can hold at `min_bytes_each` bytes per item.
    auto require_count = [&](const std::string& key, std::size_t min_bytes_each = 0,
                             std::size_t limit = max_declared_count) -> std::size_t {
        const auto [v, l] = require(key);
        const auto n = parse_int(v);
        if (!n || *n < 0)
            throw InputError(file, l, 1, key, fmt::format("expected a count ≥ 0, got \"{}\"", v));
        return require_declared_count(*n, min_bytes_each, bytes.size() - pos, at(file, l, 1, key), limit);
    };

    const auto [type_text, type_line] = require("DataType");
    const std::string type = ascii_lower(type_text);
    if (type != "ascii" && type != "binary")
        throw InputError(file, type_line, 1, "DataType",
                         fmt::format("expected ascii or binary, got \"{}\"", type_text));
    // Each value takes at least 2 bytes in ASCII ("0 ") and 4 in binary.
    const std::size_t nch = require_count("NumChannels", 0, k_max_channels);
    const std::size_t frames = require_count("NumFrames", (type == "binary" ? 4 : 2) * (1 + nch));
    if (header.count("numauxchannels")) {
        const std::size_t aux = require_count("NumAuxChannels");
        if (aux != 0)
            throw InputError(file, header["numauxchannels"].second, 1, "NumAuxChannels",
                             fmt::format("auxiliary channels are not supported, got {}", aux));
    }
    bool breaks = false;
    if (header.count("breakspresent")) {
        const auto [v, l] = header["breakspresent"];
        if (!parse_bool(v, breaks))
            throw InputError(file, l, 1, "BreaksPresent", fmt::format("expected true or false, got \"{}\"", v));
    }
    EstTrack track;
    if (header.count("equalspace")) {
        const auto [v, l] = header["equalspace"];
        if (!parse_bool(v, track.equal_space))
            throw InputError(file, l, 1, "EqualSpace", fmt::format("expected 0 or 1, got \"{}\"", v));
    }
    for (std::size_t c = 0; c < nch; ++c) {
        const auto it = channel_names.find(c);
        track.channels.push_back(it == channel_names.end() ? fmt::format("channel_{}", c) : it->second);
    }
    if (!channel_names.empty() && channel_names.rbegin()->first >= nch)
        throw InputError(file, 0, 0, fmt::format("channel_{}", channel_names.rbegin()->first),
                         fmt::format("channel index beyond NumChannels {}", nch));

    track.times_s.reserve(frames);
    track.present.reserve(frames);
    track.values.reserve(frames);
    if (type == "binary") {
        bool big = false;
        const auto [order, order_line] = require("ByteOrder");
        if (order == "10" || ascii_lower(order) == "be" || ascii_lower(order) == "msb")
            big = true;
        else if (order == "01" || ascii_lower(order) == "le" || ascii_lower(order) == "lsb")
            big = false;
        else
            throw InputError(file, order_line, 1, "ByteOrder",
                             fmt::format("expected 10 (big-endian) or 01 (little-endian), got \"{}\"", order));
        read_binary_frames(bytes, pos, file, frames, nch, breaks, big != (std::endian::native == std::endian::big),
                           track);
    } else {
        read_ascii_frames(bytes, pos, line_no, file, header.count("commentchar") ? header["commentchar"].first : "",
                          frames, nch, breaks, track);
    }
    for (std::size_t k = 1; k < track.times_s.size(); ++k)
        if (!(track.times_s[k] > track.times_s[k - 1]))
            throw InputError(file, 0, 0, fmt::format("frame {}", k + 1),
                             fmt::format("expected increasing times, got {} after {}", track.times_s[k],
                                         track.times_s[k - 1]));
    return track;
}

void write_est_track(const std::filesystem::path& path, const EstTrack& track, EstDataType type,
                     EstByteOrder order) {
    AVSI_ASSERT(track.values.size() == track.times_s.size());
    std::string out = "EST_File Track\n";
    out += type == EstDataType::Binary ? "DataType binary\n" : "DataType ascii\n";
    if (type == EstDataType::Binary)
        out += order == EstByteOrder::BigEndian ? "ByteOrder 10\n" : "ByteOrder 01\n";
    out += fmt::format("NumFrames {}\nNumChannels {}\nNumAuxChannels 0\nEqualSpace {}\n"
                       "BreaksPresent true\nCommentChar ;\n\n",
                       track.times_s.size(), track.channels.size(), track.equal_space ? 1 : 0);
    for (std::size_t c = 0; c < track.channels.size(); ++c)
        out += fmt::format("Channel_{} {}\n", c, track.channels[c]);
    out += "EST_Header_End\n";
    const bool swap =
        (order == EstByteOrder::BigEndian) != (std::endian::native == std::endian::big);
    for (std::size_t k = 0; k < track.times_s.size(); ++k) {
        AVSI_ASSERT(track.values[k].size() == track.channels.size());
        const bool present = k < track.present.size() ? track.present[k] : true;
        if (type == EstDataType::Ascii) {
            out += fmt::format("{:.6f} {}", track.times_s[k], present ? 1 : 0);
            for (float v : track.values[k]) out += fmt::format(" {}", v);
            out += '\n';
        } else {
            std::vector<float> row{static_cast<float>(track.times_s[k]), present ? 1.0f : 0.0f};
            row.insert(row.end(), track.values[k].begin(), track.values[k].end());
            for (float v : row) {
                if (swap) v = swap_float(v);
                char b[4];
                std::memcpy(b, &v, 4);
                out.append(b, 4);
            }
        }
    }
    write_text_file(path, out);
}

EstTrack read_sensor_csv(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    std::size_t time_col = table.column("time_s").value_or(table.column("time").value_or(EstTrack::npos));
    if (time_col == EstTrack::npos) time_col = table.require_column("time_s");
    EstTrack track;
    std::vector<std::size_t> cols;
    for (std::size_t c = 0; c < table.header.size(); ++c)
        if (c != time_col) {
            track.channels.push_back(table.header[c]);
            cols.push_back(c);
        }
    for (const auto& row : table.rows) {
        if (row.fields.size() != table.header.size())
            throw InputError(table.path, row.line, 1, "row",
                             fmt::format("expected {} fields, got {}", table.header.size(), row.fields.size()));
        const auto t = parse_double(row.fields[time_col]);
        if (!t)
            throw InputError(table.path, row.line, 0, table.header[time_col],
                             fmt::format("expected a time in seconds, got \"{}\"", row.fields[time_col]));
        require_time_s(*t, at(table.path, row.line, static_cast<int>(time_col) + 1, table.header[time_col]));
        std::vector<float> values;
        bool present = true;
        for (std::size_t c : cols) {
            const std::string& f = row.fields[c];
            if (f.empty() || ascii_lower(f) == "nan") {
                present = false;
                values.push_back(std::numeric_limits<float>::quiet_NaN());
                continue;
            }
            const auto v = parse_double(f);
            if (!v)
                throw InputError(table.path, row.line, 0, table.header[c],
                                 fmt::format("expected a number, empty or nan, got \"{}\"", f));
            require_in_range(*v, -k_max_track_value, k_max_track_value,
                             at(table.path, row.line, static_cast<int>(c) + 1, table.header[c]));
            values.push_back(static_cast<float>(*v));
        }
        if (!track.times_s.empty() && !(*t > track.times_s.back()))
            throw InputError(table.path, row.line, 0, table.header[time_col],
                             fmt::format("expected increasing times, got {} after {}", *t, track.times_s.back()));
        track.times_s.push_back(*t);
        track.present.push_back(present);
        track.values.push_back(std::move(values));
    }
    return track;
}

EstTrack read_sensor_file(const std::filesystem::path& path) {
    const std::string ext = ascii_lower(path.extension().string());
    if (ext == ".csv") return read_sensor_csv(path);
    if (ext == ".mat") return read_haskins_mat(path).track;
    return read_est_track(path);
}

}  // namespace avsi::learn
