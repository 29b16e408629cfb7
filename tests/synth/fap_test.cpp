// MPEG-4 FAP streams: a reader written to Xface's parsing rules parses
// avsi's output; round trip within FAPU quantisation; malformed files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "avsi/synth/fap.h"
#include "test_util.h"

namespace avsi::synth {
namespace {

Trajectory random_trajectory(std::uint64_t seed, std::size_t frames) {
    Rng rng(seed);
    Trajectory t;
    t.fps = 25.0;
    for (std::size_t k = 0; k < frames; ++k) {
        Frame f{};
        for (const auto& info : params()) f[index(info.param)] = rng.uniform(info.min, info.max);
        t.frames.push_back(f);
    }
    return t;
}

// A FAP reader following Xface's FAPFile rules, independent of avsi's:
// whitespace-separated integers; '#' comment lines; header "version name fps
// frames"; per frame a 68-flag mask line and a line "frame v…" with one
// integer per flag set (FAPs 1 and 2 must stay unset here).
struct XfaceFrame {
    std::vector<int> mask;
    std::vector<int> values;  // indexed by FAP number - 1, 0 when unset
};
std::vector<XfaceFrame> xface_read(const std::filesystem::path& path, double& fps_out) {
    std::ifstream in(path);
    std::string line;
    auto next = [&](std::string& out) {
        while (std::getline(in, out))
            if (!out.empty() && out[0] != '#') return true;
        return false;
    };
    if (!next(line)) throw std::runtime_error("no header");
    std::istringstream header(line);
    std::string version, name;
    int frames = 0;
    header >> version >> name >> fps_out >> frames;
    if (version != "2.1" || frames <= 0 || header.fail()) throw std::runtime_error("bad header: " + line);
    std::vector<XfaceFrame> out;
    for (int k = 0; k < frames; ++k) {
        XfaceFrame f;
        if (!next(line)) throw std::runtime_error("missing mask");
        std::istringstream m(line);
        for (int v; m >> v;) f.mask.push_back(v);
        if (f.mask.size() != 68) throw std::runtime_error("mask size");
        if (f.mask[0] || f.mask[1]) throw std::runtime_error("FAP 1/2 masked");
        if (!next(line)) throw std::runtime_error("missing values");
        std::istringstream v(line);
        int number = -1;
        v >> number;
        if (number != k) throw std::runtime_error("frame number");
        f.values.assign(68, 0);
        for (int i = 0; i < 68; ++i)
            if (f.mask[i] && !(v >> f.values[i])) throw std::runtime_error("missing value");
        std::string rest;
        if (v >> rest) throw std::runtime_error("extra value " + rest);
        out.push_back(f);
    }
    return out;
}

TEST(Fap, XfaceRulesReaderParsesAvsiOutput) {
    const auto dir = test::temp_dir("fap_xface");
    const Trajectory t = random_trajectory(7, 12);
    const FapStream s = trajectory_to_fap(t);
    write_fap(dir / "a.fap", s);
    double fps = 0;
    const auto frames = xface_read(dir / "a.fap", fps);
    EXPECT_EQ(fps, 25.0);
    ASSERT_EQ(frames.size(), 12u);
    for (std::size_t k = 0; k < frames.size(); ++k)
        for (int fap : mapped_faps()) {
            EXPECT_EQ(frames[k].mask[fap - 1], 1);
            EXPECT_EQ(frames[k].values[fap - 1], s.frames[k].values[fap - 1]);
        }
    // Jaw opening drives open_jaw (FAP 3, MNS units): value = mm / (MNS0 / 1024).
    const double jaw = t.frames[0][index(Param::JawRotation)];
    EXPECT_EQ(frames[0].values[2], static_cast<int>(std::lround(jaw * 12.0 / (20.0 / 1024.0))));
}

TEST(Fap, RoundTripWithinFapuQuantisation) {
    const auto dir = test::temp_dir("fap_rt");
    const Frame bound = fap_quantisation_bound();
    for (std::size_t p = 0; p < param_count; ++p) {
        EXPECT_GT(bound[p], 0.0);
        EXPECT_LT(bound[p], 0.01);  // well below anything visible
    }
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        const Trajectory t = random_trajectory(seed, 40);
        write_fap(dir / "t.fap", trajectory_to_fap(t));
        const Trajectory back = fap_to_trajectory(read_fap(dir / "t.fap"));
        EXPECT_EQ(back.fps, t.fps);
        ASSERT_EQ(back.size(), t.size());
        for (std::size_t k = 0; k < t.size(); ++k)
            for (std::size_t p = 0; p < param_count; ++p)
                EXPECT_LE(std::abs(back.frames[k][p] - t.frames[k][p]), bound[p] + 1e-12);
    }
}

TEST(Fap, ForeignFileWithVisemeFapAndPartialMask) {
    // A Greta-style file: FAP 1 set (4 values, dropped), only FAP 3 present.
    const auto dir = test::temp_dir("fap_foreign");
    std::string mask = "1 0 1";
    for (int i = 3; i < 68; ++i) mask += " 0";
    test::write_file(dir / "g.fap", "# greta\n2.1 greta 25 2\n" + mask + "\n0 3 0 50 1 512\n" + mask + "\n1 3 0 50 1 0\n");
    const FapStream s = read_fap(dir / "g.fap");
    ASSERT_EQ(s.frames.size(), 2u);
    EXPECT_FALSE(s.frames[0].mask[0]);
    const Trajectory t = fap_to_trajectory(s);
    EXPECT_NEAR(t.value(0, Param::JawRotation), 512 * (20.0 / 1024.0) / 12.0, 1e-12);
    EXPECT_EQ(t.value(0, Param::LipRounding), 0.0);  // undetermined: neutral
}

int error_line(const std::string& text) {
    const auto dir = test::temp_dir("fap_bad");
    test::write_file(dir / "b.fap", text);
    try {
        read_fap(dir / "b.fap");
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("b.fap:"), std::string::npos) << e.what();
        return e.first().line;
    }
    return -1;
}

TEST(Fap, MalformedFilesGiveFileLine) {
    std::string mask = "0 0 1";
    for (int i = 3; i < 68; ++i) mask += " 0";
    EXPECT_EQ(error_line("2.0 x 25 1\n"), 1);                                  // version
    EXPECT_EQ(error_line("# c\n2.1 x 25\n"), 2);                               // header fields
    EXPECT_EQ(error_line("2.1 x 25 1\n0 0 1\n0 5\n"), 2);                      // short mask
    EXPECT_EQ(error_line("2.1 x 25 1\n" + mask + "\n0 5 6\n"), 3);             // extra value
    EXPECT_EQ(error_line("2.1 x 25 1\n" + mask + "\n0 five\n"), 3);            // not a number
    EXPECT_EQ(error_line("2.1 x 25 2\n" + mask + "\n0 5\n" + mask + "\n7 5\n"), 5);  // frame number
    EXPECT_EQ(error_line("2.1 x 25 2\n" + mask + "\n0 5\n"), 3);               // too few frames
    EXPECT_EQ(error_line("2.1 x 25 1\n" + mask + "\n0 5\n" + mask + "\n"), 4); // too many
    std::string bad = mask;
    bad[4] = '2';
    EXPECT_EQ(error_line("2.1 x 25 1\n" + bad + "\n0 5\n"), 2);                // mask flag
}


// A mask line of `entries` flags with the given FAPs (1-based) set.
std::string mask_line(int entries, std::initializer_list<int> set, const std::string& sep = " ",
                      bool trailing = false) {
    std::string out;
    for (int i = 1; i <= entries; ++i) {
        const bool on = std::find(set.begin(), set.end(), i) != set.end();
        out += on ? "1" : "0";
        if (i < entries || trailing) out += sep;
    }
    return out;
}

// Warnings logged while running `fn`.
template <typename Fn>
std::vector<std::string> warnings_of(Fn fn) {
    auto sink = std::make_shared<MemorySink>();
    set_log_sink(sink);
    try {
        fn();
    } catch (...) {
        set_log_sink(nullptr);
        throw;
    }
    set_log_sink(nullptr);
    std::vector<std::string> out;
    for (const auto& m : sink->messages())
        if (m.level == LogLevel::Warning) out.push_back(m.text);
    return out;
}

bool any_contains(const std::vector<std::string>& lines, const std::string& what) {
    for (const auto& l : lines)
        if (l.find(what) != std::string::npos) return true;
    return false;
}

// Greta's writer: a path with spaces as the name, 69 mask entries each
// followed by a space, a set FAP 1 with one value, head and brow FAPs.
std::string greta_file() {
    std::string text = "2.1 /home/lab/greta 5/bin/Welcome back 2.fap 25 3\n";
    text += mask_line(69, {1, 3, 31, 48}, " ", true) + "\n0 7 256 40 -1200 \n";
    text += mask_line(69, {1, 3, 31, 48}, " ", true) + "\n1 7 512 60 -800 \n";
    text += mask_line(69, {3, 31, 48, 69}, " ", true) + "\n2 768 80 -400 5 \n";
    return text;
}

TEST(FapDialects, GretaHeaderWithSpacesAnd69EntryMasks) {
    const auto dir = test::temp_dir("fap_greta");
    test::write_file(dir / "greta.fap", greta_file());
    FapStream s;
    const auto warnings = warnings_of([&] { s = read_fap(dir / "greta.fap"); });
    EXPECT_EQ(s.name, "/home/lab/greta 5/bin/Welcome back 2.fap");
    EXPECT_EQ(s.fps, 25.0);
    ASSERT_EQ(s.frames.size(), 3u);
    EXPECT_EQ(s.frames[0].values[2], 256.0);  // FAP 3 after FAP 1's single value
    EXPECT_EQ(s.frames[2].values[2], 768.0);
    EXPECT_EQ(s.frames[1].values[47], -800.0);  // head_pitch kept in the stream …
    EXPECT_FALSE(s.frames[0].mask[0]);          // … the viseme dropped
    EXPECT_TRUE(s.present_in_file[0]);
    // The 69th entry set in frame 2 is reported with its line.
    EXPECT_TRUE(any_contains(warnings, "greta.fap:6: mask entries after the 68th")) << ::testing::PrintToString(warnings);
    // Decoding reports the groups present but not mapped.
    const auto decoded = warnings_of([&] { (void)decode_fap_file(dir / "greta.fap"); });
    EXPECT_TRUE(any_contains(decoded, "head rotation (FAP 48 head_pitch)")) << ::testing::PrintToString(decoded);
    EXPECT_TRUE(any_contains(decoded, "eyebrows (FAP 31 raise_l_i_eyebrow)"));
    EXPECT_TRUE(any_contains(decoded, "visemes and expressions (FAP 1 viseme)"));
    const Trajectory t = decode_fap_file(dir / "greta.fap");
    EXPECT_NEAR(t.value(2, Param::JawRotation), 768 * (20.0 / 1024.0) / 12.0, 1e-12);

    // Damaged: frame 1's mask has 67 entries (line 4), or a value is missing (line 5).
    std::string bad = greta_file();
    const std::size_t second_mask = bad.find('\n', bad.find('\n', bad.find('\n') + 1) + 1) + 1;
    bad.replace(second_mask, 4, "");  // two entries fewer
    test::write_file(dir / "greta_damaged.fap", bad);
    try {
        (void)read_fap(dir / "greta_damaged.fap");
        FAIL() << "the damaged file was read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4) << e.what();
        EXPECT_NE(std::string(e.what()).find("greta_damaged.fap:4:"), std::string::npos) << e.what();
    }
    std::string missing = greta_file();
    missing.replace(missing.find("1 7 512 60 -800"), 15, "1 7 512 60");
    test::write_file(dir / "greta_missing.fap", missing);
    try {
        (void)read_fap(dir / "greta_missing.fap");
        FAIL() << "the file with a missing value was read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 5) << e.what();
    }
}

TEST(FapDialects, XfaceCrlfWindowsPathAndPerFrameMasks) {
    const auto dir = test::temp_dir("fap_xface_crlf");
    // Xface's writer: CRLF, a Windows path as the name, a mask before every
    // frame that lists only the non-zero FAPs, decimal values; frame 1 sets
    // the viseme FAP with the specification's 4 values.
    std::string text = "# written by Xface\r\n2.1 C:\\Xface\\faps\\joy.fap 25 3\r\n";
    text += mask_line(68, {3}) + "\r\n0 102.5\r\n";
    text += mask_line(68, {1, 3, 6, 7}) + "\r\n1 3 5 50 1 204.8 240 240\r\n";
    text += mask_line(68, {6, 7, 12, 13, 53, 54, 59, 60}) + "\r\n2 240 240 150 150 240 240 150 150\r\n";
    test::write_file(dir / "joy.fap", text);
    const FapStream s = read_fap(dir / "joy.fap");
    EXPECT_EQ(s.name, "C:\\Xface\\faps\\joy.fap");
    ASSERT_EQ(s.frames.size(), 3u);
    EXPECT_TRUE(s.frames[0].mask[2]);
    EXPECT_FALSE(s.frames[0].mask[5]);
    EXPECT_EQ(s.frames[1].values[2], 204.8);
    EXPECT_EQ(s.frames[1].values[5], 240.0);
    EXPECT_TRUE(s.frames[2].mask[52]);
    EXPECT_FALSE(s.frames[2].mask[2]);
    // "Joy" stretches the corners past their range: warned, and limited with clamp.
    Trajectory kept;
    const auto warnings = warnings_of([&] { kept = decode_fap_file(dir / "joy.fap"); });
    EXPECT_GT(kept.value(2, Param::MouthCornerStretchLeft), 1.0);
    EXPECT_TRUE(any_contains(warnings, "mouth_corner_stretch_left outside its range [-0.5, 1]"))
        << ::testing::PrintToString(warnings);
    EXPECT_TRUE(any_contains(warnings, "--clamp"));
    FapDecodeSettings clamp;
    clamp.clamp = true;
    const Trajectory clamped = decode_fap_file(dir / "joy.fap", clamp);
    EXPECT_EQ(clamped.value(2, Param::MouthCornerStretchLeft), 1.0);
    EXPECT_EQ(clamped.value(1, Param::JawRotation), kept.value(1, Param::JawRotation));

    // Damaged: frame 2 (values on line 8) has one value too few.
    std::string bad = text;
    bad.replace(bad.find("2 240 240 150 150 240 240 150 150"), 33, "2 240 240 150 150 240 240 150");
    test::write_file(dir / "joy_damaged.fap", bad);
    try {
        (void)read_fap(dir / "joy_damaged.fap");
        FAIL() << "the damaged file was read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 8) << e.what();
        EXPECT_NE(std::string(e.what()).find("joy_damaged.fap:8:"), std::string::npos) << e.what();
    }
}

TEST(FapDialects, GretaTargetWrites25FpsWithGretasLayout) {
    const auto dir = test::temp_dir("fap_greta_write");
    Trajectory t = random_trajectory(3, 5);  // 25 fps
    write_fap(dir / "g.fap", trajectory_to_fap(t, {}, {}, "my stimulus"), FapTarget::Greta);
    std::ifstream in(dir / "g.fap");
    std::string header, mask, values;
    std::getline(in, header);
    std::getline(in, mask);
    std::getline(in, values);
    EXPECT_EQ(header, "2.1 my_stimulus 25 5");
    std::istringstream m(mask);
    int entries = 0;
    for (std::string w; m >> w;) ++entries;
    EXPECT_EQ(entries, 69);
    EXPECT_EQ(mask.back(), ' ');
    EXPECT_EQ(values.back(), ' ');
    // avsi reads its own Greta file back to the same values.
    const FapStream back = read_fap(dir / "g.fap");
    const FapStream orig = trajectory_to_fap(t);
    for (int fap : mapped_faps()) EXPECT_EQ(back.frames[4].values[fap - 1], orig.frames[4].values[fap - 1]);
    // A stream at another rate is refused: Greta would play it at the wrong speed.
    t.fps = 60.0;
    EXPECT_THROW(write_fap(dir / "g60.fap", trajectory_to_fap(t), FapTarget::Greta), InputError);
}

}  // namespace
}  // namespace avsi::synth
