#pragma once
// The CPU backend's element storage: structure of arrays in "half-split" order. Each lattice
// row (fixed y, z) is stored as its even-x elements followed, in a second half of every array,
// by its odd-x elements:
//
//   storage(x, y, z) = base[x & 1] + y * width[x & 1] + z * plane[x & 1] + x / 2
//
// The red-black relaxation moves one colour at a time, (x + y + z) % 2 == colour, which in a
// row is exactly one half. So each colour pass reads and writes unit-stride runs: the moving
// elements are contiguous, their -x / +x neighbours are the other half of the same row at the
// same or next index, and their +-y / +-z neighbours are the same half of the adjacent rows.
// That is what lets the relaxation run on full SIMD vectors without gathers.
//
// Strides that are multiples of 4 KiB put an element and its +-z and -x/+x neighbours, and the
// same element in every array, into the same L1 cache set; an element update reads about twenty
// such streams, more than the cache's ways, and the loads then miss. So planes, the second half
// and every array start are staggered by a few cache lines (kPlaneStagger, kHalfStagger,
// staggered allocation below): a layout detail that changes no result.
// Everything public (State, the Model) stays in linear order i = x + nx * (y + ny * z).
#include <cstdint>
#include <memory>
#include <vector>

#include "hpcm/model.hpp"
#include "hpcm/state.hpp"
#include "cpu/worker_pool.hpp"
#include "solver/bricks.hpp"

namespace hpcm::cpu {

/// Index arithmetic of the half-split order.
struct Layout {
  /// Offsets, in floats modulo 4 KiB (1024 floats), that planes and the odd half are moved to.
  static constexpr Index kPlaneStagger = 264, kHalfStagger = 520;
  Int3 dims;
  int width[2] = {0, 0};   ///< elements per row (the row stride) in the even and the odd half
  Index plane[2] = {0, 0};  ///< plane stride of each half (width * ny, staggered)
  Index base[2] = {0, 0};  ///< first element of each half
  Index size = 0;          ///< lattice elements
  Index span = 0;          ///< storage slots (elements and the stagger gaps)

  void init(Int3 d) {
    dims = d;
    width[0] = (d.x + 1) / 2;
    width[1] = d.x / 2;
    for (int h = 0; h < 2; ++h) plane[h] = staggered(static_cast<Index>(width[h]) * d.y, kPlaneStagger);
    base[0] = 0;
    base[1] = staggered(plane[0] * d.z, kHalfStagger);
    span = base[1] + plane[1] * d.z;
    size = static_cast<Index>(d.x) * d.y * d.z;
  }
  /// Storage index of lattice element (x, y, z).
  Index at(int x, int y, int z) const {
    const int h = x & 1;
    return row_start(h, y, z) + (x >> 1);
  }
  /// Storage index of linear lattice index i.
  Index at(Index i) const {
    const int x = static_cast<int>(i % dims.x);
    const Index r = i / dims.x;
    return at(x, static_cast<int>(r % dims.y), static_cast<int>(r / dims.y));
  }
  /// Start of row (y, z) of half h.
  Index row_start(int h, int y, int z) const { return base[h] + y * static_cast<Index>(width[h]) + z * plane[h]; }

 private:
  /// n rounded up to a whole number of 32-byte vectors; past 4 KiB, moved on to `offset` modulo
  /// 4 KiB (at most 4 KiB more).
  static Index staggered(Index n, Index offset) {
    n = (n + 7) / 8 * 8;
    if (n < 1024) return n;
    return n + ((offset - n % 1024) + 1024) % 1024;
  }
};

/// A float or byte array whose first element starts `lines` cache lines past a 4 KiB boundary
/// (the staggered allocation of the storage's arrays; see the top of this file).
template <class T>
class StaggeredArray {
 public:
  void assign(std::size_t n, T value, int lines) {
    constexpr std::size_t kPage = 4096 / sizeof(T);
    buf_.assign(n + 2 * kPage, value);
    const auto addr = reinterpret_cast<std::uintptr_t>(buf_.data());
    const std::uintptr_t want = static_cast<std::uintptr_t>(lines % 64) * 64;
    const std::uintptr_t skip = ((want - addr % 4096) + 4096) % 4096;
    data_ = buf_.data() + skip / sizeof(T);
    size_ = n;
  }
  T* data() { return data_; }
  const T* data() const { return data_; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  std::size_t size() const { return size_; }

 private:
  std::vector<T> buf_;
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

/// Storage-order arrays of one lattice. Positions (as displacements from rest, u = X - X0),
/// pre-ChainMail snapshot and velocities are split into their coordinates. Each link is stored as its tolerance (the Model's link_tau of
/// its table entry): the relaxation rebuilds the box limits from it, as limits_from_tau does,
/// with plain vector loads instead of table lookups. Every array carries kPad spare elements at
/// its end, so SIMD loads that run past the last element stay in the allocation.
struct Storage {
  Layout lay;
  StaggeredArray<float> p[3];        ///< u = X - X0 (u+ after the ChainMail stage)
  StaggeredArray<float> q[3];        ///< u-: frame-start displacements (equal to u between frames)
  StaggeredArray<float> v[3];        ///< V
  StaggeredArray<float> time;        ///< arrival time of the last wave
  StaggeredArray<float> weight;      ///< relaxation weight 1 / (tau + 1e-4) of the element
  StaggeredArray<float> link_tau[3];  ///< tolerance of the element's +x, +y, +z link
  StaggeredArray<std::uint8_t> tissue;
  /// Class whose speed statistics count the element: its tissue, or kTissueCount for an element
  /// outside the body (SPEC §3), which the statistics leave out.
  StaggeredArray<std::uint8_t> stat_class;
  StaggeredArray<std::uint8_t> flags;     ///< ElementFlags
  static constexpr std::size_t kPad = 16;

  /// Lays out the model's per-element data and the state (displacements, velocities, flags).
  void load(const Model& m, const State& s, WorkerPool& pool);
  /// Displacements and velocities back in linear order.
  void store_displacements(std::vector<Vec3>& disp, WorkerPool& pool) const;
  void store_state(State& s, WorkerPool& pool) const;
  /// The same for the elements of `bricks` only (the host copies already hold the others).
  void store_displacements(std::vector<Vec3>& disp, const solver::BrickGrid& grid, const std::vector<Index>& bricks,
                           WorkerPool& pool) const;
  void store_state(State& s, const solver::BrickGrid& grid, const std::vector<Index>& bricks, WorkerPool& pool) const;
  Vec3 displacement(Index linear) const {
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
