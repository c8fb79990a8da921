#pragma once
// Up-front memory estimate of a simulation lattice, shared by hpcm and hpcm-viewer: a lattice
// that cannot fit is refused with the figure before anything large is allocated (instead of
// running out of memory after minutes). The bytes per element are measured peak resident
// sizes (GNU time, phantom lattices 128^3 to 400^3, CPU backend, Release build); see
// docs/parameters.md. Candidate for the core library (plain C++, no dependency).
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

inline std::string format_gb(double bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.2f GB", bytes / 1e9);
  return buf;
}

/// Throws hpcm::Error when a lattice of `dims` at `bytes_per_element` does not fit in the
/// memory available now. `what` names the lattice in the message ("--phantom 400,400,400").
inline void check_lattice_memory(Int3 dims, double bytes_per_element, const std::string& what) {
  const double elements = double(dims.x) * double(dims.y) * double(dims.z);
  const double need = elements * bytes_per_element;
  const double avail = available_memory_bytes();
  if (avail >= 0 && need > avail) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.0f", elements);
    throw Error(what + ": a lattice of " + std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" +
                std::to_string(dims.z) + " = " + buf + " elements needs about " + format_gb(need) + " (" +
                std::to_string(int(bytes_per_element)) + " bytes per element) but " + format_gb(avail) +
                " of memory are available; use a smaller lattice (--downsample, --roi, a smaller --phantom)");
  }
}

}  // namespace hpcm::cli
