// The C3D reader (markers.h has the layout). Every error names the file, the
// part of it (header, parameter section or data, with its 512-byte block
// number counted from 1 as the format does) and the parameter.
#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"
#include "avsi/learn/markers.h"

namespace avsi::learn {
namespace {

constexpr std::size_t block_bytes = 512;
constexpr std::size_t max_frames = 100'000'000;   // 19 days at 60 fps
constexpr double max_c3d_rate_hz = 1e6;

std::size_t block_of(std::size_t byte) { return byte / block_bytes + 1; }

std::string upper(std::string s) {
    for (auto& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

// The bytes of a C3D file, read with its processor type's byte order and float format.
class C3dBytes {
public:
    C3dBytes(std::string bytes, std::string file) : m_bytes(std::move(bytes)), m_file(std::move(file)) {}

    std::size_t size() const { return m_bytes.size(); }
    const std::string& file() const { return m_file; }
    void set_processor(C3dProcessor p) { m_processor = p; }
    C3dProcessor processor() const { return m_processor; }

    std::uint8_t u8(std::size_t at) const { return static_cast<std::uint8_t>(m_bytes[at]); }
    std::int8_t i8(std::size_t at) const { return static_cast<std::int8_t>(m_bytes[at]); }
    std::uint16_t u16(std::size_t at) const {
        const std::uint16_t a = u8(at), b = u8(at + 1);
        return m_processor == C3dProcessor::Mips ? static_cast<std::uint16_t>((a << 8) | b)
                                                 : static_cast<std::uint16_t>((b << 8) | a);
    }
    std::int16_t i16(std::size_t at) const { return static_cast<std::int16_t>(u16(at)); }
    float f32(std::size_t at) const {
        std::uint8_t b[4] = {u8(at), u8(at + 1), u8(at + 2), u8(at + 3)};
        std::uint32_t u = 0;
        switch (m_processor) {
        case C3dProcessor::Intel: u = b[0] | (b[1] << 8) | (b[2] << 16) | (std::uint32_t(b[3]) << 24); break;
        case C3dProcessor::Mips: u = b[3] | (b[2] << 8) | (b[1] << 16) | (std::uint32_t(b[0]) << 24); break;
        case C3dProcessor::Dec: {
            // VAX F: the two 16-bit words of an IEEE single swapped, exponent
            // bias 128 with the hidden bit below the point: value = IEEE / 4.
            if ((b[1] & 0x7f) == 0 && (b[0] & 0x80) == 0) return 0.0f;
            u = b[2] | (b[3] << 8) | (b[0] << 16) | (std::uint32_t(b[1]) << 24);
            return std::bit_cast<float>(u) / 4.0f;
        }
        }
        return std::bit_cast<float>(u);
    }
    std::string text(std::size_t at, std::size_t n) const { return m_bytes.substr(at, n); }

    [[noreturn]] void fail(const std::string& field, const std::string& message) const {
        throw InputError(m_file, 0, 0, field, message);
    }

private:
    std::string m_bytes;
    std::string m_file;
    C3dProcessor m_processor = C3dProcessor::Intel;
};

// One parameter of the parameter section: its type (-1 char, 1 byte, 2 int16,
// 4 float), dimensions and where its data starts.
struct C3dParameter {
    int type = 0;
    std::vector<std::size_t> dims;
    std::size_t data = 0;
    std::size_t count() const {
        std::size_t n = 1;
        for (auto d : dims) n *= d;
        return n;
    }
};

using C3dParameters = std::map<std::string, C3dParameter>;  // "GROUP:NAME"

struct ParameterSection {
    std::size_t begin = 0, end = 0;  // bytes
    C3dParameters parameters;
};

// The parameter section's start from header word 1, its length and the processor type.
ParameterSection locate_parameters(C3dBytes& b) {
    if (b.size() < block_bytes)
        b.fail("header", fmt::format("block 1: a C3D file starts with a 512-byte header, the file has {} bytes", b.size()));
    if (b.u8(1) != 0x50)
        b.fail("header", fmt::format("block 1: byte 2 is 0x{:02x}, a C3D file has 0x50 there (not a C3D file?)", b.u8(1)));
    const std::size_t first = b.u8(0);
    if (first < 2) b.fail("header", fmt::format("block 1: the parameter section starts at block {}, expected 2 or later", first));
    ParameterSection s;
    s.begin = (first - 1) * block_bytes;
    if (s.begin + 4 > b.size())
        b.fail("parameters", fmt::format("block {}: the parameter section starts past the end of the file ({} bytes)", first, b.size()));
    const int processor = b.u8(s.begin + 3);
    if (processor < 84 || processor > 86)
        b.fail("parameters", fmt::format("block {}: processor type {}, expected 84 (Intel), 85 (DEC) or 86 (MIPS)", first, processor));
    b.set_processor(static_cast<C3dProcessor>(processor));
    const std::size_t blocks = b.u8(s.begin + 2);
    if (blocks == 0) b.fail("parameters", fmt::format("block {}: the parameter section has 0 blocks", first));
    s.end = s.begin + blocks * block_bytes;
    if (s.end > b.size())
        b.fail("parameters", fmt::format("blocks {}–{}: the parameter section runs past the end of the file ({} bytes, {} blocks)",
                                         first, first + blocks - 1, b.size(), (b.size() + block_bytes - 1) / block_bytes));
    return s;
}

// Reads the parameter at `pos` (after its name) into `p`; returns the byte after its data.
std::size_t read_parameter_body(const C3dBytes& b, std::size_t pos, std::size_t end, const std::string& name,
                                C3dParameter& p) {
    auto need = [&](std::size_t at, std::size_t n, const char* what) {
        if (at + n > end)
            b.fail(name, fmt::format("block {}: the parameter's {} runs past the end of the parameter section (block {})",
                                     block_of(at), what, block_of(end - 1)));
    };
    need(pos, 2, "type");
    p.type = b.i8(pos);
    if (p.type != -1 && p.type != 1 && p.type != 2 && p.type != 4)
        b.fail(name, fmt::format("block {}: data type {}, expected -1 (char), 1 (byte), 2 (int16) or 4 (float)", block_of(pos), p.type));
    const std::size_t ndims = b.u8(pos + 1);
    need(pos + 2, ndims, "dimensions");
    for (std::size_t d = 0; d < ndims; ++d) p.dims.push_back(b.u8(pos + 2 + d));
    p.data = pos + 2 + ndims;
    const std::size_t bytes = p.count() * static_cast<std::size_t>(std::abs(p.type));
    need(p.data, bytes, "data");
    return p.data + bytes;
}

// Walks the groups and parameters of the section (each entry: name length
// (negative: locked), group id (negative: a group), name, int16 offset to the
// next entry counted from the offset's own position, then its body).
C3dParameters read_parameters(const C3dBytes& b, const ParameterSection& s) {
    std::map<int, std::string> group_names;
    std::vector<std::pair<int, std::pair<std::string, C3dParameter>>> entries;
    std::size_t pos = s.begin + 4;
    while (pos + 2 <= s.end) {
        const std::size_t nlen = static_cast<std::size_t>(std::abs(b.i8(pos)));
        const int gid = b.i8(pos + 1);
        if (nlen == 0 || gid == 0) break;
        if (pos + 2 + nlen + 2 > s.end)
            b.fail("parameters", fmt::format("block {}: an entry's name runs past the end of the parameter section", block_of(pos)));
        const std::string name = upper(trim(b.text(pos + 2, nlen)));
        const std::size_t link = pos + 2 + nlen;
        const int offset = b.i16(link);
        if (gid < 0) {
            group_names[-gid] = name;
        } else {
            C3dParameter p;
            read_parameter_body(b, link + 2, s.end, fmt::format("parameter {} (group {})", name, gid), p);
            entries.push_back({gid, {name, p}});
        }
        if (offset == 0) break;
        const long long next = static_cast<long long>(link) + offset;
        if (offset < 0 || next > static_cast<long long>(s.end))
            b.fail(fmt::format("parameter {}", name),
                   fmt::format("block {}: the offset to the next entry ({}) points {} the parameter section (blocks {}–{})",
                               block_of(pos), offset, offset < 0 ? "backwards into" : "past the end of", block_of(s.begin),
                               block_of(s.end - 1)));
        pos = static_cast<std::size_t>(next);
    }
    C3dParameters out;
    for (auto& [gid, np] : entries) {
        const auto g = group_names.find(gid);
        if (g != group_names.end()) out[g->second + ":" + np.first] = np.second;
    }
    return out;
}

// Typed access to the parameters, with errors naming the parameter.
class ParameterView {
public:
    ParameterView(const C3dBytes& b, const C3dParameters& p) : m_b(b), m_p(p) {}

    const C3dParameter* find(const std::string& name) const {
        const auto it = m_p.find(name);
        return it == m_p.end() ? nullptr : &it->second;
    }
    // The first value of a numeric parameter; int16 values read unsigned when `unsigned16`.
    std::optional<double> number(const std::string& name, bool unsigned16 = false) const {
        const C3dParameter* p = find(name);
        if (!p) return std::nullopt;
        if (p->type == -1 || p->count() == 0) fail(name, p, "expected a number");
        switch (p->type) {
        case 1: return m_b.u8(p->data);
        case 2: return unsigned16 ? double(m_b.u16(p->data)) : double(m_b.i16(p->data));
        default: return m_b.f32(p->data);
        }
    }
    // A character array of dims [length, count] as `count` trimmed strings.
    std::vector<std::string> strings(const std::string& name) const {
        const C3dParameter* p = find(name);
        if (!p) return {};
        if (p->type != -1) fail(name, p, "expected characters");
        const std::size_t len = p->dims.empty() ? 1 : p->dims[0];
        const std::size_t n = p->dims.size() < 2 ? 1 : p->count() / std::max<std::size_t>(len, 1);
        std::vector<std::string> out;
        for (std::size_t i = 0; i < n; ++i) out.push_back(trim(m_b.text(p->data + i * len, len)));
        return out;
    }
    [[noreturn]] void fail(const std::string& name, const C3dParameter* p, const std::string& message) const {
        m_b.fail(name, fmt::format("block {}: {}", p ? block_of(p->data) : 0, message));
    }

private:
    const C3dBytes& m_b;
    const C3dParameters& m_p;
};

// What the data section holds, from the header and the POINT parameters
// (the parameters win where both give a value, as in other readers).
struct C3dLayout {
    std::size_t points = 0;
    std::size_t analog_per_frame = 0;  // analog values after each frame's points
    std::size_t first_frame = 1;
    std::size_t frames = 0;
    double scale = 1.0;                // < 0: float data
    double rate_hz = 0.0;
    std::size_t data_start = 0;        // block
    double mm_per_unit = 1.0;
    std::vector<std::string> labels;
    bool is_float() const { return scale < 0.0; }
    std::size_t frame_bytes() const { return (points * 4 + analog_per_frame) * (is_float() ? 4 : 2); }
};

double units_to_mm(const ParameterView& v) {
    const auto units = v.strings("POINT:UNITS");
    if (units.empty() || units[0].empty()) return 1.0;  // the format's default
    const std::string u = ascii_lower(units[0]);
    if (u == "mm") return 1.0;
    if (u == "cm") return 10.0;
    if (u == "m") return 1000.0;
    v.fail("POINT:UNITS", v.find("POINT:UNITS"), fmt::format("expected \"mm\", \"cm\" or \"m\", got \"{}\"", units[0]));
}

// The frame count and the block it was read from: POINT:LONG_FRAMES, else
// POINT:FRAMES (unsigned int16 or float), else the header's last − first + 1.
std::pair<double, std::size_t> frame_count(const C3dBytes& b, const ParameterView& v, std::size_t first) {
    for (const char* name : {"POINT:LONG_FRAMES", "POINT:FRAMES"})
        if (auto n = v.number(name, true)) return {*n, block_of(v.find(name)->data)};
    return {double(b.u16(8)) - double(first) + 1.0, 1};
}

std::vector<std::string> point_labels(const ParameterView& v, std::size_t points) {
    std::vector<std::string> labels = v.strings("POINT:LABELS");
    for (int k = 2; labels.size() < points && v.find(fmt::format("POINT:LABELS{}", k)); ++k)
        for (auto& s : v.strings(fmt::format("POINT:LABELS{}", k))) labels.push_back(s);
    if (labels.size() < points)
        v.fail("POINT:LABELS", v.find("POINT:LABELS"),
               fmt::format("{} labels for {} points (POINT:USED)", labels.size(), points));
    labels.resize(points);
    for (std::size_t i = 0; i < points; ++i) {
        if (labels[i].empty()) labels[i] = fmt::format("point{}", i + 1);
        for (std::size_t j = 0; j < i; ++j)
            if (labels[j] == labels[i])
                v.fail("POINT:LABELS", v.find("POINT:LABELS"),
                       fmt::format("points {} and {} are both labelled \"{}\"", j + 1, i + 1, labels[i]));
    }
    return labels;
}

C3dLayout read_layout(const C3dBytes& b, const ParameterView& v, const ParameterSection& s) {
    C3dLayout L;
    L.points = static_cast<std::size_t>(v.number("POINT:USED", true).value_or(b.u16(2)));
    L.analog_per_frame = b.u16(4);
    L.first_frame = std::max<std::size_t>(b.u16(6), 1);
    L.scale = v.number("POINT:SCALE").value_or(b.f32(12));
    if (!std::isfinite(L.scale) || L.scale == 0.0)
        v.fail("POINT:SCALE", v.find("POINT:SCALE"), fmt::format("expected a finite non-zero scale, got {}", L.scale));
    L.rate_hz = v.number("POINT:RATE").value_or(b.f32(20));
    if (!std::isfinite(L.rate_hz) || L.rate_hz <= 0.0 || L.rate_hz > max_c3d_rate_hz)
        v.fail("POINT:RATE", v.find("POINT:RATE"), fmt::format("expected a frame rate in (0, {}] Hz, got {}", max_c3d_rate_hz, L.rate_hz));
    const double start = v.number("POINT:DATA_START", true).value_or(b.u16(16));
    if (!((start - 1) * block_bytes >= double(s.end)) || start > 65535)
        v.fail("POINT:DATA_START", v.find("POINT:DATA_START"),
               fmt::format("the data starts at block {}, inside the header or the parameter section (blocks 1–{})", start,
                           block_of(s.end - 1)));
    L.data_start = static_cast<std::size_t>(start);
    const auto [frames, frames_block] = frame_count(b, v, L.first_frame);
    if (!std::isfinite(frames) || frames < 0 || frames > double(max_frames) || frames != std::floor(frames))
        b.fail("POINT:FRAMES", fmt::format("block {}: expected a frame count in [0, {}], got {}", frames_block, max_frames, frames));
    L.frames = static_cast<std::size_t>(frames);
    L.mm_per_unit = units_to_mm(v);
    L.labels = point_labels(v, L.points);
    return L;
}

// Checks that the data section holds every frame the layout declares.
void check_data_size(const C3dBytes& b, const C3dLayout& L) {
    const std::size_t begin = (L.data_start - 1) * block_bytes;
    const std::size_t have = begin < b.size() ? b.size() - begin : 0;
    const std::size_t need = L.frames * L.frame_bytes();
    if (need > have)
        b.fail("data", fmt::format("block {}: {} frames of {} bytes ({} points{}, {}) need {} bytes, the file has {} from there",
                                   L.data_start, L.frames, L.frame_bytes(), L.points,
                                   L.analog_per_frame ? fmt::format(" and {} analog values", L.analog_per_frame) : "",
                                   L.is_float() ? "float" : "int16", need, have));
}

// Reads the points of every frame, in mm; a negative residual word is a dropout.
void read_points(const C3dBytes& b, const C3dLayout& L, MarkerRecording& out) {
    const std::size_t begin = (L.data_start - 1) * block_bytes;
    const std::size_t word = L.is_float() ? 4 : 2;
    const double unit = L.is_float() ? L.mm_per_unit : L.mm_per_unit * L.scale;
    out.xyz.assign(L.frames * L.points * 3, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t f = 0; f < L.frames; ++f) {
        for (std::size_t m = 0; m < L.points; ++m) {
            const std::size_t at = begin + f * L.frame_bytes() + m * 4 * word;
            auto value = [&](std::size_t k) {
                return L.is_float() ? double(b.f32(at + k * word)) : double(b.i16(at + k * word));
            };
            if (value(3) < 0.0) continue;
            double* p = out.point(f, m);
            for (std::size_t k = 0; k < 3; ++k) {
                const double v = value(k);
                if (!std::isfinite(v) || std::abs(v * unit) > 1e7)
                    b.fail("data", fmt::format("block {}: frame {}, point \"{}\": coordinate {} is {} (expected a finite "
                                               "value within 10 km)", block_of(at), L.first_frame + f, L.labels[m],
                                               "xyz"[k], v));
                p[k] = v * unit;
            }
        }
    }
}

}  // namespace

MarkerRecording read_c3d(const std::filesystem::path& path) {
    C3dBytes bytes(read_text_file(path), path.string());
    const ParameterSection section = [&] {
        ParameterSection s = locate_parameters(bytes);
        s.parameters = read_parameters(bytes, s);
        return s;
    }();
    const ParameterView view(bytes, section.parameters);
    const C3dLayout layout = read_layout(bytes, view, section);
    check_data_size(bytes, layout);
    MarkerRecording out;
    out.rate_hz = layout.rate_hz;
    out.start_s = double(layout.first_frame - 1) / layout.rate_hz;
    out.labels = layout.labels;
    out.frames = layout.frames;
    read_points(bytes, layout, out);
    return out;
}

}  // namespace avsi::learn
