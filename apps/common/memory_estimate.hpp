#pragma once
// Up-front memory estimate of a simulation lattice, shared by hpcm and hpcm-viewer: a lattice
// that cannot fit is refused with the figure before anything large is allocated (instead of
// running out of memory after minutes). The bytes per element are measured peak resident
// sizes (GNU time, phantom lattices 128^3 to 400^3, CPU backend, Release build); see
// docs/parameters.md. Candidate for the core library (plain C++, no dependency).
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "hpcm/types.hpp"

namespace hpcm::cli {

/// Measured peak bytes per lattice element (volume + model + state + CPU backend buffers),
/// rounded up, per program.
inline constexpr double kRunBytesPerElement = 160;         ///< hpcm run / bench
inline constexpr double kExperimentBytesPerElement = 220;  ///< hpcm experiment (conditions in turn)
inline constexpr double kViewerBytesPerElement = 200;      ///< hpcm-viewer (adds render buffers)

namespace memory_detail {
/// First number in a file (cgroup files hold "max" when unlimited: returns -1).
inline double read_number(const char* path) {
  std::ifstream f(path);
  std::string s;
  if (!(f >> s) || s == "max") return -1;
  try {
    return std::stod(s);
  } catch (...) {
    return -1;
  }
}
}  // namespace memory_detail

/// Bytes this process can still allocate: MemAvailable of /proc/meminfo, lowered to the
/// cgroup's remaining limit (containers) when that is smaller. -1 when unknown.
inline double available_memory_bytes() {
  double avail = -1;
  {
    std::ifstream f("/proc/meminfo");
    std::string key, unit;
    double kb = 0;
    while (f >> key >> kb >> unit)
      if (key == "MemAvailable:") {
        avail = kb * 1024.0;
        break;
      }
  }
  const double v2_max = memory_detail::read_number("/sys/fs/cgroup/memory.max");
  const double v2_cur = memory_detail::read_number("/sys/fs/cgroup/memory.current");
  const double v1_max = memory_detail::read_number("/sys/fs/cgroup/memory/memory.limit_in_bytes");
  const double v1_cur = memory_detail::read_number("/sys/fs/cgroup/memory/memory.usage_in_bytes");
  for (auto [mx, cur] : {std::pair{v2_max, v2_cur}, std::pair{v1_max, v1_cur}})
    if (mx > 0 && mx < 1e18 && cur >= 0) {
      const double left = mx - cur;
      if (avail < 0 || left < avail) avail = left;
    }
  return avail;
}

/// Bytes of address space this process may still map under `ulimit -v` (RLIMIT_AS): the limit
/// less what is mapped now (/proc/self/statm). -1 when there is no limit.
inline double address_space_left_bytes() {
  rlimit lim{};
  if (::getrlimit(RLIMIT_AS, &lim) != 0 || lim.rlim_cur == RLIM_INFINITY) return -1;
  double mapped = 0;
  {
    std::ifstream f("/proc/self/statm");
    double pages = 0;
    if (f >> pages) mapped = pages * static_cast<double>(::sysconf(_SC_PAGESIZE));
  }
  const double left = static_cast<double>(lim.rlim_cur) - mapped;
  return left > 0 ? left : 0;
}

inline std::string format_gb(double bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.2f GB", bytes / 1e9);
  return buf;
}

/// Throws hpcm::Error when a lattice of `dims` at `bytes_per_element` does not fit in the
/// memory available now, nor in the address space left under `ulimit -v`: the smaller of the
/// two counts (both are named). `what` names the lattice in the message ("--phantom 400,400,400").
inline void check_lattice_memory(Int3 dims, double bytes_per_element, const std::string& what) {
  const double elements = double(dims.x) * double(dims.y) * double(dims.z);
  const double need = elements * bytes_per_element;
  const double avail = available_memory_bytes();
  const double address_space = address_space_left_bytes();
  const bool over_memory = avail >= 0 && need > avail;
  const bool over_address_space = address_space >= 0 && need > address_space;
  if (over_memory || over_address_space) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.0f", elements);
    std::string have = avail >= 0 ? format_gb(avail) + " of memory are available" : "the available memory is unknown";
    if (address_space >= 0)
      have += " and the address-space limit (ulimit -v, RLIMIT_AS) leaves " + format_gb(address_space);
    throw Error(what + ": a lattice of " + std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" +
                std::to_string(dims.z) + " = " + buf + " elements needs about " + format_gb(need) + " (" +
                std::to_string(int(bytes_per_element)) + " bytes per element) but " + have +
                "; use a smaller lattice (--downsample, --roi, a smaller --phantom)" +
                (over_address_space ? " or raise ulimit -v" : ""));
  }
}

}  // namespace hpcm::cli
