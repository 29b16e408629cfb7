// Helpers for the experiment tests: a temporary folder, a generated
// protocol + corpus of any size, a private Xvfb server and the avsi
// executable (AVSI_CLI_PATH) run in a child process.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/files.h"

namespace avsi::experiment::testing {

namespace fs = std::filesystem;

inline fs::path temp_dir(const std::string& name) {
    const fs::path p = fs::temp_directory_path() / fmt::format("avsi_exp_{}_{}", ::getpid(), name);
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
}

struct GeneratedStudy {
    int conditions = 6;
    int per_list = 3;
    int warmup = 2;
    int practice = 2;
    std::string counterbalance = "latin-square";
    bool list_column = true;
    int seed = 11;
    int extra_sentences = 0;  // unassigned sentences (no list column only)
};

// Writes protocol.toml and corpus.csv into `dir`; returns the protocol path.
inline fs::path write_study(const fs::path& dir, const GeneratedStudy& g) {
    std::string corpus = g.list_column ? "id,text,keywords,list\n" : "id,text,keywords\n";
    int n = 0;
    auto add = [&](const std::string& list) {
        ++n;
        corpus += fmt::format("s{:03},The word{} is here.,word{}", n, n, n);
        if (g.list_column) corpus += "," + list;
        corpus += "\n";
    };
    for (int i = 0; i < g.warmup; ++i) add("warmup");
    for (int i = 0; i < g.practice; ++i) add("practice");
    for (int l = 1; l <= g.conditions; ++l)
        for (int i = 0; i < g.per_list; ++i) add(std::to_string(l));
    for (int i = 0; i < g.extra_sentences; ++i) add("");
    write_text_file(dir / "corpus.csv", corpus);
    std::string protocol = fmt::format("[experiment]\nname = \"generated\"\nseed = {}\n\n[corpus]\nsentences = \"corpus.csv\"\n\n",
                                       g.seed);
    for (int c = 0; c < g.conditions; ++c) protocol += fmt::format("[[condition]]\nname = \"c{}\"\n\n", c + 1);
    protocol += fmt::format(
        "[design]\nlists = {}\nsentences_per_list = {}\nwarmup = {}\npractice = {}\ncounterbalance = \"{}\"\n\n"
        "[session]\nfullscreen = false\nfixation_ms = 100\nresponse_delay_ms = 50\n",
        g.conditions, g.per_list, g.warmup, g.practice, g.counterbalance);
    write_text_file(dir / "protocol.toml", protocol);
    return dir / "protocol.toml";
}

// Starts a private Xvfb server (1024x768x24, no TCP) and points DISPLAY at
// it; returns its pid, or -1 when /usr/bin/Xvfb is missing or did not start.
inline pid_t start_xvfb() {
    if (::access("/usr/bin/Xvfb", X_OK) != 0) return -1;
    int fds[2];
    if (::pipe(fds) != 0) return -1;
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::close(fds[0]);
        const int null = ::open("/dev/null", O_WRONLY);
        ::dup2(null, 1);
        ::dup2(null, 2);
        const std::string fd = std::to_string(fds[1]);
        ::execl("/usr/bin/Xvfb", "Xvfb", "-displayfd", fd.c_str(), "-screen", "0", "1024x768x24", "-nolisten", "tcp",
                static_cast<char*>(nullptr));
        ::_exit(127);
    }
    ::close(fds[1]);
    std::string number;
    char c = 0;
    while (::read(fds[0], &c, 1) == 1 && c != '\n') number += c;
    ::close(fds[0]);
    if (number.empty()) return -1;
    ::setenv("DISPLAY", (":" + number).c_str(), 1);
    return pid;
}

// Stops a server start_xvfb started.
inline void stop_xvfb(pid_t pid) {
    if (pid <= 0) return;
    ::kill(pid, SIGTERM);
    ::waitpid(pid, nullptr, 0);
}

// Starts `avsi` with `args`, stdout and stderr appended to `log`; returns its pid.
inline pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
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

// Runs `avsi` with `args` to the end (output appended to `log`); returns its
// exit code, -1 if it did not exit.
inline int run(const std::vector<std::string>& args, const fs::path& log) {
    int status = 0;
    ::waitpid(spawn(args, log), &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace avsi::experiment::testing
