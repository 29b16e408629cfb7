// Plausibility checks shared by the parsers (see checks.h).
#include "avsi/core/checks.h"

#include <cmath>
#include <new>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

namespace avsi {

namespace {
[[noreturn]] void fail(const Diagnostic& where, std::string message) {
    Diagnostic d = where;
    d.message = std::move(message);
    throw InputError(std::move(d));
}
}  // namespace

double require_in_range(double value, double lo, double hi, const Diagnostic& where, std::string_view what) {
    if (!std::isfinite(value) || value < lo || value > hi)
        fail(where, fmt::format("expected {} in [{:g}, {:g}], got {:g}", what, lo, hi, value));
    return value;
}

double require_time_s(double value_s, const Diagnostic& where) {
    return require_in_range(value_s, 0.0, max_time_s, where, "a time in seconds");
}

double require_near_range(double value, double lo, double hi, double factor, const Diagnostic& where) {
    const double slack = factor * (hi - lo);
    if (!std::isfinite(value) || value < lo - slack || value > hi + slack)
        fail(where, fmt::format("expected a value near the documented range [{:g}, {:g}] (within {:g} times its "
                                "width: [{:g}, {:g}]), got {:g}",
                                lo, hi, factor, lo - slack, hi + slack, value));
    return value;
}

std::size_t require_declared_count(long long declared, std::size_t min_bytes_each, std::size_t bytes_available,
                                   const Diagnostic& where, std::size_t limit) {
    if (declared < 0) fail(where, fmt::format("expected a count >= 0, got {}", declared));
    const auto n = static_cast<unsigned long long>(declared);
    if (n > limit) fail(where, fmt::format("expected a count of at most {}, got {}", limit, declared));
    if (min_bytes_each > 0 && n > bytes_available / min_bytes_each)
        fail(where, fmt::format("expected a count the file can hold ({} bytes hold at most {} of at least {} "
                                "bytes each), got {}",
                                bytes_available, bytes_available / min_bytes_each, min_bytes_each, declared));
    return static_cast<std::size_t>(n);
}

std::size_t file_size_bytes(const std::filesystem::path& path) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    if (ec) throw InputError(path, fmt::format("cannot read: {}", ec.message()));
    return static_cast<std::size_t>(size);
}

void rethrow_with_file(const std::filesystem::path& path, std::string_view doing) {
    try {
        throw;
    } catch (const InputError& e) {
        // A problem raised without a file (a model evaluating phones, a
        // value check deep inside) is about the file being read.
        bool unnamed = false;
        for (const auto& d : e.diagnostics()) unnamed = unnamed || d.path.empty();
        if (!unnamed) throw;
        std::vector<Diagnostic> named = e.diagnostics();
        for (auto& d : named)
            if (d.path.empty()) d.path = path.string();
        throw InputError(std::move(named));
    } catch (const UsageError&) {
        throw;
    } catch (const std::bad_alloc&) {
        throw InputError(path, fmt::format("out of memory while {} this file (a size in it is implausible?)", doing));
    } catch (const std::length_error& e) {
        throw InputError(path, fmt::format("a size in this file is too large while {} it ({})", doing, e.what()));
    } catch (const std::exception& e) {
        throw InputError(path, fmt::format("error while {} this file: {}", doing, e.what()));
    }
}

}  // namespace avsi
