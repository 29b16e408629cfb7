// Running the avsi executable (AVSI_CLI_PATH) from tests: to the end with its
// exit code, standard output and standard error captured (run_avsi), or in
// the background with its output appended to a log file (start_avsi, for a
// session a test watches or kills).
#pragma once

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/files.h"
#include "support/temp_dir.h"

namespace avsi::test {

struct CliResult {
    int exit_code = -1;  // -1: did not exit (a signal)
    std::string out;
    std::string err;
    // Both streams, standard output first (for messages that may be on either).
    std::string output() const { return out + err; }
};

// `s` in single quotes for /bin/sh.
inline std::string shell_quote(const std::string& s) {
    std::string out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

// Runs a /bin/sh command line (with its own redirections of standard input,
// if any), capturing its standard output and error.
inline CliResult run_command(const std::string& command_line) {
    static std::atomic<int> count{0};
    static const std::filesystem::path dir = temp_dir("run_command");
    const std::string stem = std::to_string(count++);
    const std::filesystem::path out = dir / (stem + ".out"), err = dir / (stem + ".err");
    const std::string command =
        "{ " + command_line + " ; } >" + shell_quote(out.string()) + " 2>" + shell_quote(err.string());
    const int status = std::system(command.c_str());
    CliResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = read_text_file(out);
    r.err = read_text_file(err);
    std::filesystem::remove(out);
    std::filesystem::remove(err);
    return r;
}

// Runs `avsi <args>` as typed in a shell (args already quoted where needed;
// "<file" redirects standard input).
inline CliResult run_avsi(const std::string& args) { return run_command(shell_quote(AVSI_CLI_PATH) + " " + args); }

// Runs avsi with `args`, each one argument.
inline CliResult run_avsi(const std::vector<std::string>& args) {
    std::string line;
    for (const std::string& a : args) line += (line.empty() ? "" : " ") + shell_quote(a);
    return run_avsi(line);
}

// Starts avsi with `args` in the background, standard output and error
// appended to `log`; returns its process id (wait_avsi waits for it).
inline pid_t start_avsi(const std::vector<std::string>& args, const std::filesystem::path& log) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        const int out = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
        ::dup2(out, 1);
        ::dup2(out, 2);
        std::vector<char*> argv;
        argv.push_back(const_cast<char*>(AVSI_CLI_PATH));
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execv(AVSI_CLI_PATH, argv.data());
        ::_exit(127);
    }
    return pid;
}

// How a process start_avsi started ended.
struct Finished {
    int exit_code = -1;      // -1: it did not exit (a signal)
    long peak_rss_kib = 0;   // its peak resident set size (wait4's ru_maxrss)
};

// Waits for a process start_avsi started.
inline Finished wait_avsi(pid_t pid) {
    Finished f;
    int status = 0;
    rusage usage{};
    if (pid > 0 && ::wait4(pid, &status, 0, &usage) == pid) {
        f.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        f.peak_rss_kib = usage.ru_maxrss;
    }
    return f;
}

// Runs avsi with `args` to the end, output appended to `log`; returns its
// exit code (-1: a signal).
inline int run_avsi_logged(const std::vector<std::string>& args, const std::filesystem::path& log) {
    return wait_avsi(start_avsi(args, log)).exit_code;
}

}  // namespace avsi::test
