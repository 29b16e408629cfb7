// Optical marker files: C3D written here (c3d_test_writer.h, from the format
// guide) in the three processor formats, int16 and float, with residual-
// flagged dropouts and analog values to skip, read back to the same known
// positions; Qualisys TSV and Motive CSV of the same positions; malformed C3D
// refused with the file and the block; `avsi markers` writes the CSV.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/learn/markers.h"
#include "c3d_test_writer.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::learn;
using avsi::test::C3dCpu;
using avsi::test::C3dWriteSpec;

namespace {

constexpr double no_value = std::numeric_limits<double>::quiet_NaN();

// Known positions in mm, multiples of 1/8 mm (exact in int16 × 0.125 and in
// float): 4 markers × 7 frames; marker 2 drops out at frames 2–3, marker 0 at 6.
C3dWriteSpec known_spec() {
    C3dWriteSpec s;
    s.labels = {"ULIP", "LLIP", "JAW", "NOSE"};
    s.frames = 7;
    for (std::size_t f = 0; f < s.frames; ++f)
        for (std::size_t m = 0; m < s.labels.size(); ++m) {
            const bool dropout = (m == 2 && (f == 2 || f == 3)) || (m == 0 && f == 6);
            for (int k = 0; k < 3; ++k)
                s.xyz.push_back(dropout ? no_value : -120.5 + 37.25 * double(m) + 0.125 * double(f * (k + 1)) + 10.0 * k);
        }
    return s;
}

void expect_known(const MarkerRecording& r, const C3dWriteSpec& s, const std::string& what) {
    SCOPED_TRACE(what);
    ASSERT_EQ(r.labels, s.labels);
    ASSERT_EQ(r.frames, s.frames);
    EXPECT_DOUBLE_EQ(r.rate_hz, s.rate_hz);
    for (std::size_t f = 0; f < s.frames; ++f)
        for (std::size_t m = 0; m < s.labels.size(); ++m) {
            const double* want = s.xyz.data() + (f * s.labels.size() + m) * 3;
            EXPECT_EQ(r.seen(f, m), !std::isnan(want[0])) << "frame " << f << " marker " << m;
            if (!r.seen(f, m)) continue;
            for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.point(f, m)[k], want[k], 1e-9) << f << " " << m << " " << k;
        }
}

fs::path write_spec(const std::string& name, const C3dWriteSpec& s) {
    const fs::path p = test::temp_dir("markers") / name;
    test::write_c3d_file(p, s);
    return p;
}

std::string error_of(const fs::path& p) {
    try {
        read_c3d(p);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(C3dReader, ThreeProcessorsIntAndFloatReadIdentically) {
    for (C3dCpu cpu : {C3dCpu::Intel, C3dCpu::Dec, C3dCpu::Mips})
        for (bool floats : {false, true}) {
            C3dWriteSpec s = known_spec();
            s.cpu = cpu;
            s.floats = floats;
            s.analog_per_frame = 3;
            const std::string name = fmt::format("cpu{}_{}.c3d", int(cpu), floats ? "float" : "int");
            expect_known(read_c3d(write_spec(name, s)), s, name);
        }
}

TEST(C3dReader, ProcessorFormatsDifferOnDisk) {
    // The same data is laid out differently: a reader that ignored the
    // processor type could not read all three.
    C3dWriteSpec s = known_spec();
    s.floats = true;
    const std::string intel = test::c3d_file_bytes(s);
    s.cpu = C3dCpu::Dec;
    const std::string dec = test::c3d_file_bytes(s);
    s.cpu = C3dCpu::Mips;
    const std::string mips = test::c3d_file_bytes(s);
    EXPECT_NE(intel.substr(512 * 2), dec.substr(512 * 2));
    EXPECT_NE(intel.substr(512 * 2), mips.substr(512 * 2));
}

TEST(C3dReader, MetresAreConvertedToMillimetres) {
    C3dWriteSpec s = known_spec();
    s.floats = true;
    s.units = "m";
    for (auto& v : s.xyz) v /= 1000.0;
    const MarkerRecording r = read_c3d(write_spec("metres.c3d", s));
    EXPECT_NEAR(r.point(1, 1)[0], known_spec().xyz[(1 * 4 + 1) * 3], 1e-4);
}

TEST(C3dReader, MalformedFilesNameTheFileAndBlock) {
    const C3dWriteSpec good = known_spec();
    const std::string bytes = test::c3d_file_bytes(good);
    auto case_file = [&](const std::string& name, const std::string& content) {
        const fs::path p = test::temp_dir("markers") / name;
        std::ofstream(p, std::ios::binary) << content;
        return p;
    };
    // Truncated data block: the last 512-byte block cut off.
    const fs::path truncated = case_file("truncated.c3d", bytes.substr(0, bytes.size() - 512));
    EXPECT_NE(error_of(truncated).find(truncated.string()), std::string::npos);
    EXPECT_NE(error_of(truncated).find("data: block 3:"), std::string::npos) << error_of(truncated);
    // A parameter whose offset to the next entry points past the section's end.
    std::string past = bytes;
    past[512 + 4 + 2 + 5] = '\x10';  // the POINT group's offset, low byte…
    past[512 + 4 + 2 + 5 + 1] = '\x10';  // …and high byte: 4112 bytes on
    const std::string past_err = error_of(case_file("pointer.c3d", past));
    EXPECT_NE(past_err.find("points past the end of the parameter section"), std::string::npos) << past_err;
    EXPECT_NE(past_err.find("block 2"), std::string::npos) << past_err;
    // A header claiming 10⁹ frames.
    C3dWriteSpec huge = good;
    huge.frames_as_float = 1e9;
    const std::string huge_err = error_of(write_spec("huge.c3d", huge));
    EXPECT_NE(huge_err.find("POINT:FRAMES: block 2: expected a frame count in [0, 100000000], got 1000000000"), std::string::npos) << huge_err;
    // A NaN scale.
    C3dWriteSpec bad_scale = good;
    bad_scale.scale_mm = no_value;
    const std::string scale_err = error_of(write_spec("nan_scale.c3d", bad_scale));
    EXPECT_NE(scale_err.find("POINT:SCALE: block 2: expected a finite non-zero scale, got nan"), std::string::npos)
        << scale_err;
    // Not a C3D file at all.
    const std::string text_err = error_of(case_file("text.c3d", std::string(600, 'a')));
    EXPECT_NE(text_err.find("header: block 1"), std::string::npos) << text_err;
}

TEST(MarkerText, QualisysTsvReadsTheSamePositions) {
    const C3dWriteSpec s = known_spec();
    std::string tsv = fmt::format("NO_OF_FRAMES\t{}\nNO_OF_CAMERAS\t8\nNO_OF_MARKERS\t4\nFREQUENCY\t60\n"
                                  "NO_OF_ANALOG\t0\nDATA_INCLUDED\t3D\nMARKER_NAMES\tULIP\tLLIP\tJAW\tNOSE\n"
                                  "Frame\tTime\tULIP X\tULIP Y\tULIP Z\tLLIP X\tLLIP Y\tLLIP Z\tJAW X\tJAW Y\tJAW Z"
                                  "\tNOSE X\tNOSE Y\tNOSE Z\n",
                                  s.frames);
    for (std::size_t f = 0; f < s.frames; ++f) {
        tsv += fmt::format("{}\t{:.5f}", f + 1, double(f) / 60.0);
        for (std::size_t m = 0; m < 4; ++m) {
            const double* x = s.xyz.data() + (f * 4 + m) * 3;
            // QTM writes gaps as empty cells or as zeros; both forms here.
            if (std::isnan(x[0])) tsv += f % 2 ? "\t\t\t" : "\t0.000\t0.000\t0.000";
            else tsv += fmt::format("\t{:.3f}\t{:.3f}\t{:.3f}", x[0], x[1], x[2]);
        }
        tsv += "\n";
    }
    const fs::path p = test::temp_dir("markers") / "qtm.tsv";
    write_text_file(p, tsv);
    expect_known(read_marker_file(p), s, "qualisys");
}

TEST(MarkerText, MotiveCsvReadsTheSamePositions) {
    const C3dWriteSpec s = known_spec();
    std::string csv = "Format Version,1.23,Take Name,t1,Capture Frame Rate,60.000000,Export Frame Rate,60.000000,"
                      "Length Units,Meters,Coordinate Space,Global\n\nType,,Rigid Body,";
    std::string name = "Name,,Head,", id = "ID,,1,", prop = ",,Rotation,", axis = "Frame,Time (Seconds),X,";
    for (std::size_t m = 0; m < 4; ++m)
        for (const char* a : {"X", "Y", "Z"}) {
            csv += "Marker,";
            name += "Face:" + s.labels[m] + ",";
            id += "ID,";
            prop += "Position,";
            axis += std::string(a) + ",";
        }
    auto cut = [](std::string line) { return line.substr(0, line.size() - 1) + "\n"; };
    csv = cut(csv) + cut(name) + cut(id) + cut(prop) + cut(axis);
    for (std::size_t f = 0; f < s.frames; ++f) {
        csv += fmt::format("{},{:.6f},0.1", f, double(f) / 60.0);
        for (std::size_t m = 0; m < 4; ++m) {
            const double* x = s.xyz.data() + (f * 4 + m) * 3;
            if (std::isnan(x[0])) csv += ",,,";
            else csv += fmt::format(",{:.6f},{:.6f},{:.6f}", x[0] / 1000, x[1] / 1000, x[2] / 1000);
        }
        csv += "\n";
    }
    const fs::path p = test::temp_dir("markers") / "motive.csv";
    write_text_file(p, csv);
    MarkerRecording r = read_marker_file(p);
    for (auto& l : r.labels) l = l.substr(5);  // "Face:"
    expect_known(r, s, "motive");
}

TEST(MarkersCommand, WritesTimeAndMillimetresWithEmptyDropouts) {
    C3dWriteSpec s = known_spec();
    s.cpu = C3dCpu::Mips;
    const fs::path dir = test::temp_dir("markers_cli");
    const fs::path in = dir / "cli.c3d", out = dir / "cli.csv";
    test::write_c3d_file(in, s);
    const auto r = test::run_avsi({"markers", in.string(), "--out", out.string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const std::string csv = read_text_file(out);
    EXPECT_EQ(csv.substr(0, csv.find('\n')),
              "time_s,ULIP_x,ULIP_y,ULIP_z,LLIP_x,LLIP_y,LLIP_z,JAW_x,JAW_y,JAW_z,NOSE_x,NOSE_y,NOSE_z");
    // Frame 2 (third row): JAW drops out; ULIP at (-120.5 + 0.25, -110.5 + 0.5, -100.5 + 0.75).
    std::size_t at = 0;
    for (int i = 0; i < 3; ++i) at = csv.find('\n', at) + 1;
    EXPECT_EQ(csv.substr(at, csv.find('\n', at) - at),
              "0.033333,-120.250,-110.000,-99.750,-83.000,-72.750,-62.500,,,,-8.500,1.750,12.000");
    const auto bad = test::run_avsi({"markers", (dir / "x.trc").string(), "--out", out.string()});
    EXPECT_EQ(bad.exit_code, 1);
    EXPECT_NE(bad.err.find("unsupported marker file extension '.trc'"), std::string::npos) << bad.err;
}
