#pragma once
// Vector helpers of the CPU kernels, on GCC vector types: the same source is compiled 4-wide
// for SSE2 (simd_sse2.cpp) and 8-wide for AVX2 (simd_avx2.cpp). The operators are plain IEEE
// single precision, lane by lane, so a kernel written with them performs the floating-point
// operations of the scalar rule it mirrors, in the same order, and gives the same bits.
#include <cstdint>
#include <cstring>

#include "core/lanes.hpp"

namespace hpcm::cpu::simd {

template <class V>
inline V load(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V>
inline void store(float* p, V v) {
  std::memcpy(p, &v, sizeof v);
}
template <class V>
inline V splat(float x) {
  return V{} + x;
}
template <class V>
inline V vmax(V a, V b) {
  return a > b ? a : b;  // exactly the scalar ternary a > b ? a : b
}
template <class V>
inline V vmin(V a, V b) {
  return a < b ? a : b;
}

// hpcm::add_exact / sub_exact (a + b and a - b, one rounding each) are in core/lanes.hpp: the
// rules the kernels share use them, and the AVX-512 file specialises them.

// Per instruction set (defined in simd_sse2.cpp / simd_avx2.cpp before the kernels):
template <class V>
using Mask = decltype(V{} < V{});
/// N flag or tissue bytes widened to int lanes.
template <class V>
Mask<V> load_bytes(const std::uint8_t* p);
/// Square root of each lane (IEEE, correctly rounded).
template <class V>
V vsqrt(V a);
/// Bit l set when lane l of the mask is set.
template <class V>
unsigned lane_bits(Mask<V> m);
/// Stores the lanes of v whose bit is set in `bits` to p[l]; the other floats at p are neither
/// read nor written (a masked store where the instruction set has one).
template <class V>
void store_lanes(float* p, V v, unsigned bits);

/// Calls f(column, lanes) once for every column of the row that holds a lane set in `bits`,
/// with the set lanes of that column: lane l is element `first + l` of the row, counted from
/// the row's column origin, and columns are 2^col_shift elements wide. Once per column rather
/// than once per lane: with every lane set, one call for each column instead of N, and a loop
/// whose trip count the branch predictor learns.
template <class F>
inline void for_each_column(unsigned bits, int first, int col_shift, int n, F&& f) {
  while (bits) {
    const int lane = __builtin_ctz(bits);
    const int col = (first + lane) >> col_shift;
    const int next = ((col + 1) << col_shift) - first;  // first lane of the next column
    const unsigned col_lanes = next >= n ? bits : bits & ((1u << next) - 1u);
    f(col, col_lanes);
    bits &= ~col_lanes;
  }
}

/// Sets cols[c] = 1 for every column c that holds a lane set in `bits` (as for_each_column).
/// Vectors that start on a column boundary and hold whole columns (the common case: runs start
/// at a brick column and vectors are a power of two wide) take a loop of fixed length.
/// `whole_vector`: every lane of the vector belongs to the run, so every column it covers is
/// the run's to write; the loop then has no branch per column (on a CT the columns that moved
/// are scattered, and the branch would be mispredicted).
inline void mark_columns(unsigned bits, int first, int col_shift, int n, std::uint8_t* cols, bool whole_vector = false) {
  if (!bits && !whole_vector) return;
  const int width = 1 << col_shift;
  if ((first & (width - 1)) == 0 && width <= n && width < 32) {
    const unsigned column_lanes = (1u << width) - 1u;
    std::uint8_t* const c0 = cols + (first >> col_shift);
    for (int c = 0; c < n >> col_shift; ++c) {
      const bool moved = ((bits >> (c * width)) & column_lanes) != 0;
      if (whole_vector)
        c0[c] = static_cast<std::uint8_t>(c0[c] | moved);
      else if (moved)
        c0[c] = 1;
    }
    return;
  }
  for_each_column(bits, first, col_shift, n, [cols](int c, unsigned) { cols[c] = 1; });
}

/// Software prefetch for streams the hardware prefetcher does not keep up with: the element
/// kernels read a dozen or more arrays side by side, more streams than it tracks. Issued once
/// per 64-byte line of floats (every vector at 16 lanes, every second or fourth at 8 or 4).
/// Prefetches never fault and change no result.
inline constexpr int kPrefetchLine = 16;
template <int N>
inline bool prefetch_due(int j) {
  return N >= kPrefetchLine || (j & (kPrefetchLine - 1)) < N;
}
inline void prefetch(const void* p) { __builtin_prefetch(p); }

}  // namespace hpcm::cpu::simd
