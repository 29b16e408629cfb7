#include "avsi/core/files.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "avsi/core/error.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

using test::temp_dir;

TEST(Files, WriteThenReadRoundTripsAndCreatesFolders) {
    const auto dir = temp_dir("files");
    const auto path = dir / "a" / "b" / "x.txt";
    write_text_file(path, "hello\nworld");
    EXPECT_EQ(read_text_file(path), "hello\nworld");
    // no temporaries left behind
    int count = 0;
    for ([[maybe_unused]] auto& e : fs::directory_iterator(path.parent_path())) ++count;
    EXPECT_EQ(count, 1);
    fs::remove_all(dir);
}

TEST(Files, UncommittedAtomicFileLeavesOriginalUntouched) {
    const auto dir = temp_dir("atomic");
    const auto path = dir / "data.csv";
    write_text_file(path, "original");
    {
        AtomicFile f(path);
        std::FILE* out = std::fopen(f.temp_path().c_str(), "w");
        std::fputs("partial", out);
        std::fclose(out);
        // destroyed without commit, as when a writer throws
    }
    EXPECT_EQ(read_text_file(path), "original");
    fs::remove_all(dir);
}

TEST(Files, MissingFileIsAnInputErrorNamingIt) {
    try {
        read_text_file("/nonexistent/avsi.txt");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, "/nonexistent/avsi.txt");
        EXPECT_NE(std::string(e.what()).find("no such file"), std::string::npos);
    }
}

TEST(Sha256, KnownVectors) {
    EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    const auto dir = temp_dir("sha");
    write_text_file(dir / "abc.txt", "abc");
    EXPECT_EQ(sha256_file(dir / "abc.txt"), sha256_hex("abc"));
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi
