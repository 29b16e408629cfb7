// Shared helpers for the synth tests (and learn's, which include them): phone
// sequences; temporary folders are tests/support's.
#pragma once

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "support/temp_dir.h"

namespace avsi::synth::test {

using avsi::test::temp_dir;

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
