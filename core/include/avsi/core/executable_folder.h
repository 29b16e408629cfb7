// The folder of the running executable, header-only: the front end (which
// links no avsi library) finds its helpers by it, and avsi_core its Festival
// server (docs/cli-design.md).
#pragma once

#include <limits.h>
#include <unistd.h>

#include <string>

namespace avsi {

// From /proc/self/exe, so symlinks and a relative argv[0] do not matter;
// empty if it cannot be read.
inline std::string executable_folder() {
    char path[PATH_MAX];
    const ssize_t n = ::readlink("/proc/self/exe", path, sizeof path - 1);
    if (n <= 0) return {};
    path[n] = '\0';
    std::string folder(path);
    const std::size_t slash = folder.rfind('/');
    return slash == std::string::npos ? std::string() : folder.substr(0, slash);
}

}  // namespace avsi
