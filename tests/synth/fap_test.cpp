// MPEG-4 FAP streams: a reader written to Xface's parsing rules parses
// avsi's output; round trip within FAPU quantisation; malformed files.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "avsi/core/error.h"
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

}  // namespace
}  // namespace avsi::synth
