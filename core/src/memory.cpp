// Available memory from the kernel's files and the process's limits (memory.h).
#include "avsi/core/memory.h"

#include <sys/resource.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>

namespace avsi {
namespace {

// The value in kB of `key` ("MemAvailable:") in a /proc file, in bytes; 0 if absent.
std::uint64_t proc_kb(const char* path, const std::string& key) {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(key, 0) == 0) {
            std::istringstream fields(line.substr(key.size()));
            std::uint64_t kb = 0;
            if (fields >> kb) return kb * 1024;
        }
    return 0;
}

// A cgroup v2 file holding one number ("max" when unlimited); 0 if absent or "max".
std::uint64_t cgroup_number(const char* path) {
    std::ifstream in(path);
    std::uint64_t value = 0;
    return in >> value ? value : 0;
}

}  // namespace

std::uint64_t available_memory_bytes() {
    std::uint64_t available = k_memory_unknown;
    if (const std::uint64_t machine = proc_kb("/proc/meminfo", "MemAvailable:"); machine > 0)
        available = std::min(available, machine);
    if (const std::uint64_t limit = cgroup_number("/sys/fs/cgroup/memory.max"); limit > 0) {
        const std::uint64_t used = cgroup_number("/sys/fs/cgroup/memory.current");
        available = std::min(available, limit > used ? limit - used : 0);
    }
    rlimit address_space{};
    if (::getrlimit(RLIMIT_AS, &address_space) == 0 && address_space.rlim_cur != RLIM_INFINITY) {
        const std::uint64_t size = proc_kb("/proc/self/status", "VmSize:");
        const auto limit = static_cast<std::uint64_t>(address_space.rlim_cur);
        available = std::min(available, limit > size ? limit - size : 0);
    }
    return available;
}

}  // namespace avsi
