// Running the avsi executable (AVSI_CLI_PATH) from end-to-end tests: one
// helper for every test that checks exit codes, stdout and stderr.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "avsi/core/files.h"

namespace avsi::test {

struct CliResult {
    int exit_code = -1;
    std::string out;
    std::string err;
};

// `s` in single quotes for /bin/sh.
inline std::string shell_quote(const std::string& s) {
    std::string out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

// Runs `avsi <args>` (args already shell-quoted where needed), capturing
// stdout and stderr through files in `dir`.
inline CliResult run_avsi(const std::string& args, const std::filesystem::path& dir) {
    const std::filesystem::path out = dir / "stdout.txt", err = dir / "stderr.txt";
    const std::string command = shell_quote(AVSI_CLI_PATH) + " " + args + " >" + shell_quote(out.string()) +
                                " 2>" + shell_quote(err.string());
    const int status = std::system(command.c_str());
    CliResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = read_text_file(out);
    r.err = read_text_file(err);
    return r;
}

}  // namespace avsi::test
