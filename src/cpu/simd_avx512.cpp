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
}  // namespace hpcm::cpu::simd

#include "cpu/layer_simd.hpp"
#include "cpu/link_check_simd.hpp"
#include "cpu/relax_simd.hpp"

namespace hpcm::cpu {

SimdKernels kernels_avx512() {
  SimdKernels k;
  k.relax = [](const RelaxContext& c, const RelaxRun& r) { return simd::relax_run<simd::f16>(c, r); };
  k.layer = [](Storage& st, const dynamics::LayerConstants& lc, const LayerRow& row, SpeedStats* sp) {
    simd::layer_row<simd::f16>(st, lc, row, sp);
  };
  k.link_check = [](const Storage& st, const solver::Wall& w, int h, int y, int z, int j0, int j1, std::vector<int>& out) {
    return simd::link_check_row<simd::f16>(st, w, h, y, z, j0, j1, out);
  };
  k.name = "avx512";
  return k;
}

}  // namespace hpcm::cpu
