// The CPU kernels on 16-wide vectors. This file alone is compiled for AVX-512 (F, VL, DQ, BW;
// no FMA contraction: the build uses -ffp-contract=off), and its kernels run only where the
// CPU reports those extensions (select_kernels). Same source as the 4- and 8-wide paths.
// GCC 12's AVX-512 intrinsics start from _mm512_undefined_*(), which -Wmaybe-uninitialized
// reports inside the system header; the values are fully written.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>

#include <algorithm>

#include "cpu/simd.hpp"

namespace hpcm::cpu::simd {
typedef float f16 __attribute__((vector_size(64)));
typedef int i16 __attribute__((vector_size(64)));

template <>
inline i16 load_bytes<f16>(const std::uint8_t* p) {
  return reinterpret_cast<i16>(_mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p))));
}
template <>
inline f16 vsqrt<f16>(f16 a) {
  return reinterpret_cast<f16>(_mm512_sqrt_ps(reinterpret_cast<__m512>(a)));
}
template <>
inline unsigned lane_bits<f16>(i16 m) {
  return static_cast<unsigned>(_mm512_movepi32_mask(reinterpret_cast<__m512i>(m)));
}
template <>
inline void store_lanes<f16>(float* p, f16 v, unsigned bits) {
  _mm512_mask_storeu_ps(p, static_cast<__mmask16>(bits), reinterpret_cast<__m512>(v));
}
}  // namespace hpcm::cpu::simd

#include "cpu/kernel_table.hpp"

namespace hpcm::cpu {

SimdKernels kernels_avx512() { return simd::kernel_table<simd::f16>("avx512"); }

}  // namespace hpcm::cpu
