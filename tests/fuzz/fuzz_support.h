// Shared by the libFuzzer harnesses (issue 19): each harness writes the input
// to a temporary file with the parser's extension, calls the parser, and
// accepts only success or avsi::InputError. Anything else escaping (a
// library's exception, std::bad_alloc) is a finding: it is rethrown, and
// libFuzzer reports it as a crash (an uncaught exception aborts).
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

#include "avsi/core/error.h"

namespace avsi::fuzz {

// Inputs larger than this are skipped: the parsers' size limits are tested
// by the malformed corpus, the fuzzer looks for logic errors.
inline constexpr std::size_t max_input_bytes = 1 << 20;

// A file in a per-process folder, rewritten for every input.
inline std::filesystem::path input_file(std::string_view name, std::string_view data) {
    // Removed when the process exits normally (a crash leaves it for a look).
    struct Folder {
        std::filesystem::path path;
        ~Folder() {
            std::error_code ec;
            std::filesystem::remove_all(path, ec);
        }
    };
    static const Folder dir{[] {
        const char* tmp = std::getenv("TMPDIR");
        auto d = std::filesystem::path(tmp && *tmp ? tmp : "/tmp") / ("avsi_fuzz_" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        return d;
    }()};
    const auto path = dir.path / name;
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(data.data(), static_cast<std::streamsize>(data.size()));
    return path;
}

// Runs `parse`; InputError is the expected answer to bad input.
template <class Parse>
int run(const std::uint8_t* data, std::size_t size, Parse&& parse) {
    if (size > max_input_bytes) return -1;
    try {
        parse(std::string_view(reinterpret_cast<const char*>(data), size));
    } catch (const avsi::InputError& e) {
        // The message must name a place: a file (or "<input>" for in-memory text).
        if (e.diagnostics().empty() || std::string(e.what()).find("error: ") == std::string::npos) __builtin_trap();
        // AVSI_FUZZ_VERBOSE=1: say why an input was refused (checking that a good seed passes).
        static const bool verbose = std::getenv("AVSI_FUZZ_VERBOSE") != nullptr;
        if (verbose) std::fprintf(stderr, "refused: %s\n", e.what());
    }
    return 0;
}

}  // namespace avsi::fuzz
