#pragma once
// Brick-sparse bookkeeping: the lattice is tiled into B^3 bricks; only bricks that changed,
// and their face neighbours, are processed in the next sweep (SPEC §4), so the cost per
// frame follows the moving region, not the volume.
#include <cstdint>
#include <vector>

#include "hpcm/types.hpp"

namespace hpcm::solver {

struct BrickGrid {
  Int3 dims;        ///< lattice dims
  int size = 8;     ///< B
  Int3 nb;          ///< bricks per axis
  Index count = 0;

  void init(Int3 lattice, int brick_size);
  Index brick_of(int x, int y, int z) const { return x / size + static_cast<Index>(nb.x) * (y / size + static_cast<Index>(nb.y) * (z / size)); }
  Index brick_of_index(Index i) const;
  /// Element range [lo, hi) of brick b.
  void range(Index b, Int3& lo, Int3& hi) const;
  /// List of bricks with flag set, or adjacent (face) to one: the next sweep's work list.
  void dilate_to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out) const;
  /// List of bricks with flag set.
  static void to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out);
};

}  // namespace hpcm::solver
