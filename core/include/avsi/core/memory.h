// How much memory a process can still take, for refusing work that would
// not fit before it starts (the vocoder's whole-signal paths) rather than
// being killed part-way.
//
//   if (need > avsi::available_memory_bytes()) throw ...;
#pragma once

#include <cstdint>
#include <limits>

namespace avsi {

constexpr std::uint64_t k_memory_unknown = std::numeric_limits<std::uint64_t>::max();

// The least of: the machine's available memory (MemAvailable in
// /proc/meminfo); the cgroup's limit less its use (cgroup v2 memory.max
// minus memory.current: a cluster job's or a container's limit); and the
// address-space limit (RLIMIT_AS, `ulimit -v`) less this process's size
// (VmSize in /proc/self/status). k_memory_unknown when none of them is set
// or readable.
std::uint64_t available_memory_bytes();

}  // namespace avsi
