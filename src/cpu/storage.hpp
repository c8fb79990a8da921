#pragma once
// The CPU backend's element storage: structure of arrays in "half-split" order. Each lattice
// row (fixed y, z) is stored as its even-x elements followed, in a second half of every array,
// by its odd-x elements:
//
//   storage(x, y, z) = base[x & 1] + (y + ny * z) * width[x & 1] + x / 2
//
// The red-black relaxation moves one colour at a time, (x + y + z) % 2 == colour, which in a
// row is exactly one half. So each colour pass reads and writes unit-stride runs: the moving
// elements are contiguous, their -x / +x neighbours are the other half of the same row at the
// same or next index, and their +-y / +-z neighbours are the same half of the adjacent rows.
// That is what lets the relaxation run on full SIMD vectors without gathers.
// Everything public (State, the Model) stays in linear order i = x + nx * (y + ny * z).
#include <cstdint>
#include <memory>
#include <vector>

#include "hpcm/model.hpp"
#include "hpcm/state.hpp"

namespace hpcm::cpu {

/// Index arithmetic of the half-split order.
struct Layout {
  Int3 dims;
  int width[2] = {0, 0};  ///< elements per row in the even and the odd half
  Index base[2] = {0, 0};  ///< first element of each half
  Index size = 0;

  void init(Int3 d) {
    dims = d;
    width[0] = (d.x + 1) / 2;
    width[1] = d.x / 2;
    const Index rows = static_cast<Index>(d.y) * d.z;
    base[0] = 0;
    base[1] = rows * width[0];
    size = static_cast<Index>(d.x) * rows;
  }
  Index row(int y, int z) const { return y + static_cast<Index>(dims.y) * z; }
  /// Storage index of lattice element (x, y, z).
  Index at(int x, int y, int z) const {
    const int h = x & 1;
    return base[h] + row(y, z) * width[h] + (x >> 1);
  }
  /// Storage index of linear lattice index i.
  Index at(Index i) const {
    const int x = static_cast<int>(i % dims.x);
    const Index r = i / dims.x;
    const int h = x & 1;
    return base[h] + r * width[h] + (x >> 1);
  }
  /// Start of row (y, z) of half h.
  Index row_start(int h, int y, int z) const { return base[h] + row(y, z) * width[h]; }
};

/// Storage-order arrays of one lattice. Positions, pre-ChainMail snapshot and velocities are
/// split into their coordinates. Each link is stored as its tolerance (the Model's link_tau of
/// its table entry): the relaxation rebuilds the box limits from it, as limits_from_tau does,
/// with plain vector loads instead of table lookups. Every array carries kPad spare elements at
/// its end, so SIMD loads that run past the last element stay in the allocation.
struct Storage {
  Layout lay;
  std::vector<float> p[3];        ///< X (X+ after the ChainMail stage)
  std::vector<float> q[3];        ///< X-: frame-start positions (equal to X between frames)
  std::vector<float> v[3];        ///< V
  std::vector<float> time;        ///< arrival time of the last wave
  std::vector<float> weight;      ///< relaxation weight 1 / (tau + 1e-4) of the element
  std::vector<float> link_tau[3];  ///< tolerance of the element's +x, +y, +z link
  std::vector<std::uint8_t> tissue;
  std::vector<std::uint8_t> flags;     ///< ElementFlags
  static constexpr std::size_t kPad = 16;

  /// Lays out the model's per-element data and the state (positions, velocities, flags).
  void load(const Model& m, const State& s);
  /// Positions and velocities back in linear order.
  void store_positions(std::vector<Vec3>& pos) const;
  void store_state(State& s) const;
  Vec3 position(Index linear) const {
    const Index k = lay.at(linear);
    return {p[0][k], p[1][k], p[2][k]};
  }
  /// Bytes per element held by these arrays.
  /// Box limits of the +a link of the element at storage index k (w is not stored: 1).
  LinkLimits link(int a, Index k) const { return limits_from_tau(link_tau[a][static_cast<std::size_t>(k)], 1.0f); }
  static constexpr std::size_t bytes_per_element() {
    return 9 * sizeof(float) + 2 * sizeof(float) + 3 * sizeof(float) + 2 * sizeof(std::uint8_t);
  }
};

}  // namespace hpcm::cpu
