// A C3D writer for the tests and the benchmark, written from the format's
// user guide (c3d.org) independently of the reader in learn/src/c3d.cpp:
// header block, a POINT parameter group, int16 or float data in Intel, DEC
// (VAX F floats) or MIPS (big-endian) byte order, a residual word of −1 for a
// dropout (NaN coordinates in the input).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace avsi::test {

enum class C3dCpu { Intel = 84, Dec = 85, Mips = 86 };

struct C3dWriteSpec {
    C3dCpu cpu = C3dCpu::Intel;
    bool floats = false;              // float data (POINT:SCALE < 0) or int16
    double scale_mm = 0.125;          // int16: mm per unit (also the residual unit)
    double rate_hz = 60.0;
    std::string units = "mm";         // POINT:UNITS; coordinates are written in these units
    std::size_t analog_per_frame = 0; // analog values after each frame's points (written as 0)
    std::vector<std::string> labels;
    std::size_t frames = 0;
    std::vector<double> xyz;          // frames × labels × 3 in `units`; NaN: dropout
    // Broken files for the malformed tests: a POINT:FRAMES written as this
    // float instead of the true count (0: the true count, int16).
    double frames_as_float = 0.0;
};

namespace detail {

class C3dBuffer {
public:
    explicit C3dBuffer(C3dCpu cpu) : m_cpu(cpu) {}
    std::string bytes;

    void u8(int v) { bytes.push_back(static_cast<char>(v & 0xff)); }
    void i16(int v) {
        const auto u = static_cast<std::uint16_t>(static_cast<std::int16_t>(v));
        if (m_cpu == C3dCpu::Mips) {
            u8(u >> 8);
            u8(u);
        } else {
            u8(u);
            u8(u >> 8);
        }
    }
    void f32(double value) {
        float f = static_cast<float>(value);
        if (m_cpu == C3dCpu::Dec) f *= 4.0f;  // VAX F = IEEE / 4
        const auto u = std::bit_cast<std::uint32_t>(f);
        switch (m_cpu) {
        case C3dCpu::Intel: u8(u); u8(u >> 8); u8(u >> 16); u8(u >> 24); break;
        case C3dCpu::Mips: u8(u >> 24); u8(u >> 16); u8(u >> 8); u8(u); break;
        case C3dCpu::Dec:
            if (f == 0.0f) { u8(0); u8(0); u8(0); u8(0); break; }
            u8(u >> 16); u8(u >> 24); u8(u); u8(u >> 8);  // the two 16-bit words swapped
            break;
        }
    }
    void text(const std::string& s, std::size_t width) {
        for (std::size_t i = 0; i < width; ++i) bytes.push_back(i < s.size() ? s[i] : ' ');
    }
    void pad_to_block() {
        while (bytes.size() % 512) bytes.push_back('\0');
    }

private:
    C3dCpu m_cpu;
};

// One parameter entry of group 1 ("POINT"): name, offset to the next entry,
// type, dimensions, data (already encoded), empty description.
inline void c3d_parameter(C3dBuffer& b, const std::string& name, int type, const std::vector<int>& dims,
                          const std::string& data) {
    b.u8(static_cast<int>(name.size()));
    b.u8(1);
    b.text(name, name.size());
    b.i16(static_cast<int>(2 + 2 + dims.size() + data.size() + 1));
    b.u8(type);
    b.u8(static_cast<int>(dims.size()));
    for (int d : dims) b.u8(d);
    b.bytes += data;
    b.u8(0);
}

inline std::string c3d_encoded(C3dCpu cpu, auto&& write) {
    C3dBuffer b(cpu);
    write(b);
    return b.bytes;
}

}  // namespace detail

// The bytes of a C3D file holding `spec`.
inline std::string c3d_file_bytes(const C3dWriteSpec& spec) {
    using detail::C3dBuffer;
    const int points = static_cast<int>(spec.labels.size());
    const double scale = spec.floats ? -spec.scale_mm : spec.scale_mm;
    // Parameters first (their size fixes the data start, which they hold).
    std::size_t label_len = 4;
    for (const auto& l : spec.labels) label_len = std::max(label_len, l.size());
    auto enc = [&](auto&& f) { return detail::c3d_encoded(spec.cpu, f); };
    auto parameters = [&](int data_start) {
        C3dBuffer p(spec.cpu);
        p.u8(1);
        p.u8(0x50);
        p.u8(0);  // block count, set below
        p.u8(static_cast<int>(spec.cpu));
        p.u8(5);
        p.u8(-1);  // group 1
        p.text("POINT", 5);
        p.i16(3);
        p.u8(0);
        detail::c3d_parameter(p, "USED", 2, {}, enc([&](C3dBuffer& b) { b.i16(points); }));
        detail::c3d_parameter(p, "SCALE", 4, {}, enc([&](C3dBuffer& b) { b.f32(scale); }));
        detail::c3d_parameter(p, "RATE", 4, {}, enc([&](C3dBuffer& b) { b.f32(spec.rate_hz); }));
        detail::c3d_parameter(p, "DATA_START", 2, {}, enc([&](C3dBuffer& b) { b.i16(data_start); }));
        if (spec.frames_as_float != 0.0)
            detail::c3d_parameter(p, "FRAMES", 4, {}, enc([&](C3dBuffer& b) { b.f32(spec.frames_as_float); }));
        else
            detail::c3d_parameter(p, "FRAMES", 2, {}, enc([&](C3dBuffer& b) { b.i16(static_cast<int>(spec.frames)); }));
        detail::c3d_parameter(p, "UNITS", -1, {static_cast<int>(spec.units.size())},
                              enc([&](C3dBuffer& b) { b.text(spec.units, spec.units.size()); }));
        detail::c3d_parameter(p, "LABELS", -1, {static_cast<int>(label_len), points}, enc([&](C3dBuffer& b) {
                                  for (const auto& l : spec.labels) b.text(l, label_len);
                              }));
        p.u8(0);  // end of the parameters
        p.u8(0);
        p.pad_to_block();
        p.bytes[2] = static_cast<char>(p.bytes.size() / 512);
        return p;
    };
    const int data_start = 2 + static_cast<int>(parameters(0).bytes.size() / 512);
    const C3dBuffer p = parameters(data_start);
    // The header block.
    C3dBuffer h(spec.cpu);
    h.u8(2);
    h.u8(0x50);
    h.i16(points);
    h.i16(static_cast<int>(spec.analog_per_frame));
    h.i16(1);
    h.i16(static_cast<int>(std::min<std::size_t>(spec.frames, 65535)));
    h.i16(10);
    h.f32(scale);
    h.i16(data_start);
    h.i16(0);
    h.f32(spec.rate_hz);
    h.pad_to_block();
    // The data: x y z residual per point, then the analog values.
    C3dBuffer d(spec.cpu);
    const int residual_word = 0x0300 | 2;  // cameras 1 and 2, residual 2 units
    for (std::size_t f = 0; f < spec.frames; ++f) {
        for (int m = 0; m < points; ++m) {
            const double* x = spec.xyz.data() + (f * points + m) * 3;
            const bool dropout = std::isnan(x[0]);
            for (int k = 0; k < 3; ++k) {
                const double v = dropout ? 0.0 : x[k];
                if (spec.floats) d.f32(v);
                else d.i16(static_cast<int>(std::lround(v / spec.scale_mm)));
            }
            if (spec.floats) d.f32(dropout ? -1.0 : residual_word);
            else d.i16(dropout ? -1 : residual_word);
        }
        for (std::size_t a = 0; a < spec.analog_per_frame; ++a) {
            if (spec.floats) d.f32(0.0);
            else d.i16(0);
        }
    }
    d.pad_to_block();
    return h.bytes + p.bytes + d.bytes;
}

inline void write_c3d_file(const std::filesystem::path& path, const C3dWriteSpec& spec) {
    const std::string bytes = c3d_file_bytes(spec);
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace avsi::test
