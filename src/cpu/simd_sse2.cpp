// The CPU kernels on 4-wide vectors (SSE2: every x86-64 CPU).
#include <emmintrin.h>

#include <algorithm>

#include "cpu/simd.hpp"

namespace hpcm::cpu::simd {
typedef float f4 __attribute__((vector_size(16)));
typedef int i4 __attribute__((vector_size(16)));

template <>
inline i4 load_bytes<f4>(const std::uint8_t* p) {
  std::uint32_t w;
  std::memcpy(&w, p, sizeof w);
  return i4{static_cast<int>(w & 0xff), static_cast<int>(w >> 8 & 0xff), static_cast<int>(w >> 16 & 0xff),
            static_cast<int>(w >> 24)};
}
template <>
inline f4 vsqrt<f4>(f4 a) {
  return reinterpret_cast<f4>(_mm_sqrt_ps(reinterpret_cast<__m128>(a)));
}
template <>
inline unsigned lane_bits<f4>(i4 m) {
  return static_cast<unsigned>(_mm_movemask_ps(reinterpret_cast<__m128>(m)));
}
template <>
inline void store_lanes<f4>(float* p, f4 v, unsigned bits) {
  for (int l = 0; l < 4; ++l)
    if (bits >> l & 1u) p[l] = v[l];
}
}  // namespace hpcm::cpu::simd

#include "cpu/kernel_table.hpp"

namespace hpcm::cpu {

SimdKernels kernels_sse2() { return simd::kernel_table<simd::f4>("sse2"); }

}  // namespace hpcm::cpu
