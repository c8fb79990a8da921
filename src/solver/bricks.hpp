#pragma once
// Brick geometry of the sparse schedule (SPEC §4), written once for both backends: the lattice
// is tiled into B^3 bricks; only bricks that changed, and their face neighbours, are processed
// in the next sweep, so the cost per frame follows the moving region, not the volume.
// Plain data with HPCM_HD methods: the CUDA kernels carry a BrickGrid by value.
#include <cstdint>
#include <vector>

#include "hpcm/types.hpp"

namespace hpcm::solver {

struct BrickGrid {
  Int3 dims;        ///< lattice dims
  int size = 8;     ///< B
  Int3 nb;          ///< bricks per axis
  Index count = 0;

  void init(Int3 lattice, int brick_size) {
    dims = lattice;
    size = brick_size;
    nb = {(dims.x + size - 1) / size, (dims.y + size - 1) / size, (dims.z + size - 1) / size};
    count = static_cast<Index>(nb.x) * nb.y * nb.z;
  }
  HPCM_HD Index brick_of(int x, int y, int z) const {
    return x / size + static_cast<Index>(nb.x) * (y / size + static_cast<Index>(nb.y) * (z / size));
  }
  HPCM_HD Index brick_of_index(Index i) const {
    const int x = static_cast<int>(i % dims.x);
    const Index r = i / dims.x;
    return brick_of(x, static_cast<int>(r % dims.y), static_cast<int>(r / dims.y));
  }
  HPCM_HD Int3 brick_coords(Index b) const {
    const int bx = static_cast<int>(b % nb.x);
    const Index r = b / nb.x;
    return {bx, static_cast<int>(r % nb.y), static_cast<int>(r / nb.y)};
  }
  /// Element range [lo, hi) of brick b.
  HPCM_HD void range(Index b, Int3& lo, Int3& hi) const {
    const Int3 c = brick_coords(b);
    lo = {c.x * size, c.y * size, c.z * size};
    hi = {lo.x + size < dims.x ? lo.x + size : dims.x, lo.y + size < dims.y ? lo.y + size : dims.y,
          lo.z + size < dims.z ? lo.z + size : dims.z};
  }
  /// True when brick b or one of its face neighbours has its flag set (the next sweep's work).
  template <class Flags>
  HPCM_HD bool flagged_or_face_neighbour(const Flags& flags, Index b) const {
    if (flags[b]) return true;
    const Int3 c = brick_coords(b);
    const Index sy = nb.x, sz = static_cast<Index>(nb.x) * nb.y;
    return (c.x > 0 && flags[b - 1]) || (c.x + 1 < nb.x && flags[b + 1]) || (c.y > 0 && flags[b - sy]) ||
           (c.y + 1 < nb.y && flags[b + sy]) || (c.z > 0 && flags[b - sz]) || (c.z + 1 < nb.z && flags[b + sz]);
  }
  /// f(n) for each face neighbour n of brick b inside the grid.
  template <class F>
  HPCM_HD void for_each_face_neighbour(Index b, F&& f) const {
    const Int3 c = brick_coords(b);
    const Index sy = nb.x, sz = static_cast<Index>(nb.x) * nb.y;
    if (c.x > 0) f(b - 1);
    if (c.x + 1 < nb.x) f(b + 1);
    if (c.y > 0) f(b - sy);
    if (c.y + 1 < nb.y) f(b + sy);
    if (c.z > 0) f(b - sz);
    if (c.z + 1 < nb.z) f(b + sz);
  }
  /// Host: list of bricks with flag set, or adjacent (face) to one.
  void dilate_to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out) const;
  /// Host: list of bricks with flag set.
  static void to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out);
};

}  // namespace hpcm::solver
