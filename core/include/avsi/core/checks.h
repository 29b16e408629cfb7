// Plausibility checks for values read from files, shared by every parser
// (issue 19): finite numbers within a stated range, times within a stated
// maximum, counts declared in a header checked against the file's real size
// before anything is allocated, and the boundary that turns a library's
// exception (allocation, length) into an InputError naming the file.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/error.h"

namespace avsi {

// The latest time any label, track, trajectory or stimulus may reach: one
// hour. Far above a stimulus or a corpus utterance (seconds); low enough that
// a trajectory sampled at 1000 fps over it still fits in memory (3.6 M
// frames × 10 parameters × 8 bytes = 288 MB). Longer recordings are split.
inline constexpr double max_time_s = 3600.0;

// The most items (frames, channels, vertices…) a header may declare whatever
// the file size: 10^8.
inline constexpr std::size_t max_declared_count = 100'000'000;

// A place in an input (path, line, column, field) for the checks below.
inline Diagnostic at(std::string path, int line, int column, std::string field) {
    return Diagnostic{std::move(path), line, column, std::move(field), {}};
}

// `value` if it is finite and in [lo, hi]; otherwise throws InputError at
// `where` (path, line, column, field): "expected <what> in [lo, hi], got v".
double require_in_range(double value, double lo, double hi, const Diagnostic& where,
                        std::string_view what = "a number");

// A time in seconds in [0, max_time_s].
double require_time_s(double value_s, const Diagnostic& where);

// A value of a quantity documented to lie in [lo, hi], allowed to overshoot
// by `factor` times the range's width on either side (measured data and other
// tools' files overshoot a little; 1e300 is garbage).
double require_near_range(double value, double lo, double hi, double factor, const Diagnostic& where);

// A count declared in a header (frames, channels, vertices): at most `limit`
// and at most what `bytes_available` bytes can hold when each item takes at
// least `min_bytes_each` bytes. Throws InputError at `where` otherwise.
std::size_t require_declared_count(long long declared, std::size_t min_bytes_each, std::size_t bytes_available,
                                   const Diagnostic& where, std::size_t limit = max_declared_count);

// The size of a file in bytes; InputError naming it if it cannot be read.
std::size_t file_size_bytes(const std::filesystem::path& path);

// Call inside a catch block: rethrows an InputError (giving `path` to its
// diagnostics that name no file) and re-raises
// anything else (std::bad_alloc, std::length_error, a library's
// std::exception) as an InputError naming `path` and the cause.
[[noreturn]] void rethrow_with_file(const std::filesystem::path& path, std::string_view doing = "reading");

// Runs `read()` and re-raises what escapes it through rethrow_with_file.
template <class Read>
auto with_file_context(const std::filesystem::path& path, Read&& read) -> decltype(read()) {
    try {
        return read();
    } catch (...) {
        rethrow_with_file(path);
    }
}

}  // namespace avsi
