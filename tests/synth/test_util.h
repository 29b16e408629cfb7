// Shared helpers for the synth tests: temporary folders and phone sequences.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "avsi/core/phones.h"

namespace avsi::synth::test {

// A fresh temporary folder for one test.
inline std::filesystem::path temp_dir(const std::string& name) {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("avsi_synth_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

inline void write_file(const std::filesystem::path& path, const std::string& text) {
    std::ofstream(path) << text;
}

// Contiguous phones from (symbol, duration) pairs, starting at 0.
inline PhoneSequence make_phones(const std::vector<std::pair<std::string, double>>& items) {
    PhoneSequence out;
    double t = 0.0;
    for (const auto& [symbol, duration] : items) {
        out.push_back({symbol, t, t + duration, false});
        t += duration;
    }
    return out;
}

}  // namespace avsi::synth::test
