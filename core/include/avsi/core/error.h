// Errors with source locations (file:line:col: error: field: …), exit codes,
// and the programmer-error assertion. Every module reports bad input through
// avsi::InputError so the CLI prints one compiler-style format everywhere.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/closest_match.h"  // did-you-mean hints beside the errors that give them

namespace avsi {

// Process exit codes shared by every command.
enum ExitCode : int { ExitSuccess = 0, ExitFailure = 1, ExitUsage = 2 };

// One problem found in one input: where it is, which field, what was wrong.
// line/column are 1-based; 0 means "not applicable" and is left out when printed.
struct Diagnostic {
    std::string path;
    int line = 0;
    int column = 0;
    std::string field;    // e.g. "vocoder.bands", "tier 'phones' interval 3"
    std::string message;  // e.g. "expected an integer in [1, 32], got \"three\""

    // "path:line:col: error: field: message", omitting empty parts.
    std::string format() const;
};

// Bad input (files, arguments, media). Holds one or more diagnostics so a
// validator can report every problem in a file at once and fail once.
class InputError : public std::runtime_error {
public:
    explicit InputError(Diagnostic diagnostic);
    explicit InputError(std::vector<Diagnostic> diagnostics);
    InputError(std::string path, int line, int column, std::string field, std::string message);
    // An error about a whole file (no line), e.g. "cannot open: No such file".
    InputError(const std::filesystem::path& path, std::string message);

    const std::vector<Diagnostic>& diagnostics() const { return m_diagnostics; }
    const Diagnostic& first() const { return m_diagnostics.front(); }

private:
    std::vector<Diagnostic> m_diagnostics;
};

// A wrong command line (exit code 2).
class UsageError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Collects diagnostics while validating a whole input, then throws once.
class DiagnosticList {
public:
    void add(Diagnostic diagnostic) { m_items.push_back(std::move(diagnostic)); }
    void add(std::string path, int line, int column, std::string field, std::string message);
    bool empty() const { return m_items.empty(); }
    std::size_t size() const { return m_items.size(); }
    // Throws InputError with every collected diagnostic if there is any.
    void throw_if_any() const;

private:
    std::vector<Diagnostic> m_items;
};

// The start of `text` for a message: at most `max_bytes` bytes (not cutting
// a UTF-8 character), with "…" and the full length when cut.
std::string excerpt(std::string_view text, std::size_t max_bytes = 60);

namespace detail {
[[noreturn]] void assertion_failed(const char* expression, const char* file, int line);
}  // namespace detail

}  // namespace avsi

// Programmer errors: print file:line and abort. Not for bad input.
#define AVSI_ASSERT(cond) \
    ((cond) ? static_cast<void>(0) : ::avsi::detail::assertion_failed(#cond, __FILE__, __LINE__))
