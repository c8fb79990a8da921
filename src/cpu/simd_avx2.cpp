// The CPU kernels on 8-wide vectors. This file alone is compiled with -mavx2 (not FMA), and
// its kernels run only where the CPU reports AVX2 (select_kernels).
#include <immintrin.h>

#include <algorithm>

#include "cpu/simd.hpp"

namespace hpcm::cpu::simd {
typedef float f8 __attribute__((vector_size(32)));
typedef int i8 __attribute__((vector_size(32)));

template <>
inline i8 load_bytes<f8>(const std::uint8_t* p) {
  return reinterpret_cast<i8>(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p))));
}
template <>
inline f8 vsqrt<f8>(f8 a) {
  return reinterpret_cast<f8>(_mm256_sqrt_ps(reinterpret_cast<__m256>(a)));
}
template <>
inline unsigned lane_bits<f8>(i8 m) {
  return static_cast<unsigned>(_mm256_movemask_ps(reinterpret_cast<__m256>(m)));
}
template <>
inline void store_lanes<f8>(float* p, f8 v, unsigned bits) {
  const i8 lane_bit = {1, 2, 4, 8, 16, 32, 64, 128};
  const i8 mask = (lane_bit & static_cast<int>(bits)) != 0;
  _mm256_maskstore_ps(p, reinterpret_cast<__m256i>(mask), reinterpret_cast<__m256>(v));
}
}  // namespace hpcm::cpu::simd

#include "cpu/kernel_table.hpp"

namespace hpcm::cpu {

SimdKernels kernels_avx2() { return simd::kernel_table<simd::f8>("avx2"); }

}  // namespace hpcm::cpu
