// Frame-count rule and trajectory CSV I/O.
#include <gtest/gtest.h>

#include "avsi/core/error.h"
#include "avsi/synth/trajectory.h"
#include "test_util.h"

namespace avsi::synth {
namespace {

TEST(FrameCount, FollowsCeilRule) {
    EXPECT_EQ(frame_count(1.0, 60.0), 60u);        // 0 … 59/60, last frame covers the end
    EXPECT_EQ(frame_count(1.001, 60.0), 61u);
    EXPECT_EQ(frame_count(0.5, 25.0), 13u);        // 12.5 frames → 13
    EXPECT_EQ(frame_count(1.066, 90.0), 96u);      // 95.94 → 96
    EXPECT_EQ(frame_count(0.1 * 3, 10.0), 3u);     // 0.30000000000000004 s: rounding noise does not add a frame
    EXPECT_EQ(frame_count(0.0, 60.0), 0u);
}

TEST(TrajectoryCsv, RoundTripsExactly) {
    const auto dir = test::temp_dir("csv");
    Trajectory t;
    t.fps = 60.0;
    for (int k = 0; k < 7; ++k) {
        Frame f{};
        for (std::size_t p = 0; p < param_count; ++p) f[p] = 0.1 * k - 0.037 * double(p) + 1e-13;
        t.frames.push_back(f);
    }
    write_trajectory_csv(dir / "t.csv", t);
    const Trajectory back = read_trajectory_csv(dir / "t.csv");
    EXPECT_EQ(back.fps, 60.0);
    ASSERT_EQ(back.size(), t.size());
    for (std::size_t k = 0; k < t.size(); ++k) EXPECT_EQ(back.frames[k], t.frames[k]);
}

TEST(TrajectoryCsv, AcceptsColumnsInAnyOrder) {
    const auto dir = test::temp_dir("csv_order");
    std::string header = "jaw_shift,time_s";
    std::string row0 = "0.5,0", row1 = "0.25,0.04";
    for (const auto& info : params()) {
        if (info.param == Param::JawShift) continue;
        header += std::string(",") + std::string(info.name);
        row0 += ",0";
        row1 += ",0";
    }
    test::write_file(dir / "t.csv", header + "\n" + row0 + "\n" + row1 + "\n");
    const Trajectory t = read_trajectory_csv(dir / "t.csv");
    EXPECT_EQ(t.fps, 25.0);
    EXPECT_EQ(t.value(1, Param::JawShift), 0.25);
}

TEST(TrajectoryCsv, UnevenStepNamesTheLine) {
    const auto dir = test::temp_dir("csv_bad");
    std::string header = "time_s", zeros;
    for (const auto& info : params()) {
        header += std::string(",") + std::string(info.name);
        zeros += ",0";
    }
    test::write_file(dir / "t.csv", header + "\n0" + zeros + "\n0.1" + zeros + "\n0.25" + zeros + "\n");
    try {
        read_trajectory_csv(dir / "t.csv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4);
        EXPECT_NE(std::string(e.what()).find("constant frame step"), std::string::npos) << e.what();
    }
}

TEST(TrajectoryCsv, MissingParameterColumnIsAnError) {
    const auto dir = test::temp_dir("csv_missing");
    test::write_file(dir / "t.csv", "time_s,jaw_rotation\n0,0\n0.1,0\n");
    EXPECT_THROW(read_trajectory_csv(dir / "t.csv"), InputError);
}

}  // namespace
}  // namespace avsi::synth
