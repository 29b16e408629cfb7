// A private X server for the tests that open windows (the session runner,
// the player): Xvfb, GL through Mesa.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

namespace avsi::test {

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

}  // namespace avsi::test
