// A temporary folder of its own for each test. Every test executable's tests
// include the headers of tests/support/ as "support/<name>.h".
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

namespace avsi::test {

// <tmp>/avsi_<pid>_<name>, emptied and created: the process id keeps the
// tests ctest runs in parallel (one process each) apart, the name the
// folders of one process.
inline std::filesystem::path temp_dir(const std::string& name) {
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("avsi_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

}  // namespace avsi::test
