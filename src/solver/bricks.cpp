#include "solver/bricks.hpp"

#include <algorithm>

namespace hpcm::solver {

void BrickGrid::init(Int3 lattice, int brick_size) {
  dims = lattice;
  size = brick_size;
  nb = {(dims.x + size - 1) / size, (dims.y + size - 1) / size, (dims.z + size - 1) / size};
  count = static_cast<Index>(nb.x) * nb.y * nb.z;
}

Index BrickGrid::brick_of_index(Index i) const {
  const int x = static_cast<int>(i % dims.x);
  const Index r = i / dims.x;
  return brick_of(x, static_cast<int>(r % dims.y), static_cast<int>(r / dims.y));
}

void BrickGrid::range(Index b, Int3& lo, Int3& hi) const {
  const int bx = static_cast<int>(b % nb.x);
  const Index r = b / nb.x;
  const int by = static_cast<int>(r % nb.y), bz = static_cast<int>(r / nb.y);
  lo = {bx * size, by * size, bz * size};
  hi = {std::min(dims.x, lo.x + size), std::min(dims.y, lo.y + size), std::min(dims.z, lo.z + size)};
}

void BrickGrid::dilate_to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out) const {
  out.clear();
  for (int bz = 0; bz < nb.z; ++bz)
    for (int by = 0; by < nb.y; ++by)
      for (int bx = 0; bx < nb.x; ++bx) {
        const Index b = bx + static_cast<Index>(nb.x) * (by + static_cast<Index>(nb.y) * bz);
        bool on = flags[b];
        if (!on && bx > 0) on = flags[b - 1];
        if (!on && bx + 1 < nb.x) on = flags[b + 1];
        if (!on && by > 0) on = flags[b - nb.x];
        if (!on && by + 1 < nb.y) on = flags[b + nb.x];
        if (!on && bz > 0) on = flags[b - static_cast<Index>(nb.x) * nb.y];
        if (!on && bz + 1 < nb.z) on = flags[b + static_cast<Index>(nb.x) * nb.y];
        if (on) out.push_back(b);
      }
}

void BrickGrid::to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out) {
  out.clear();
  for (Index b = 0; b < static_cast<Index>(flags.size()); ++b)
    if (flags[b]) out.push_back(b);
}

}  // namespace hpcm::solver
