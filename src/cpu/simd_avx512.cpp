// The CPU kernels on 16-wide vectors. This file alone is compiled for AVX-512 (F, VL, DQ, BW;
// no FMA contraction: the build uses -ffp-contract=off), and its kernels run only where the
// CPU reports those extensions (select_kernels). Same source as the 4- and 8-wide paths.
// GCC 12's AVX-512 intrinsics start from _mm512_undefined_*(), which -Wmaybe-uninitialized and
// -Wuninitialized report inside the system header; the values are fully written.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <immintrin.h>

#include <algorithm>

#include "cpu/simd.hpp"
#include "solver/rules.hpp"

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

namespace hpcm {
using cpu::simd::f16;
// a * 1 + b and b * -1 + a round once, exactly as a + b and a - b (signed zeros included).
template <>
inline f16 add_exact<f16>(f16 a, f16 b) {
  return reinterpret_cast<f16>(
      _mm512_fmadd_ps(reinterpret_cast<__m512>(a), _mm512_set1_ps(1.0f), reinterpret_cast<__m512>(b)));
}
template <>
inline f16 sub_exact<f16>(f16 a, f16 b) {
  return reinterpret_cast<f16>(
      _mm512_fnmadd_ps(reinterpret_cast<__m512>(b), _mm512_set1_ps(1.0f), reinterpret_cast<__m512>(a)));
}
}  // namespace hpcm

namespace hpcm::solver {
// relax_coordinate's step back on mask registers (same bits as the definition in
// solver/rules.hpp: tests/solver/test_rules_once.cpp). With d = t - cur and q != 0, d has the
// sign of q (rounding is monotone and omega > 0), so "q > 0 ? d >= limit : d <= limit" is
// |d| >= |limit|, and a NaN fails both; the toward-zero step is a masked subtraction, the other
// a masked addition, of one on the bit pattern, and a step back that lands on zero takes the
// float next to zero on cur's side.
template <>
inline f16 relax_coordinate<f16>(f16 cur, f16 q, f16 omega) {
  const f16 t = cur + omega * q;
  const __m512 mq = reinterpret_cast<__m512>(q), mt = reinterpret_cast<__m512>(t), mcur = reinterpret_cast<__m512>(cur);
  const __m512 zero = _mm512_setzero_ps();
  const __m512 d = reinterpret_cast<__m512>(t - cur), limit = reinterpret_cast<__m512>((0.5f * (2.0f + omega)) * q);
  const __mmask16 nonzero = _mm512_cmp_ps_mask(mq, zero, _CMP_NEQ_UQ);
  const __mmask16 back = _mm512_mask_cmp_ps_mask(nonzero, _mm512_abs_ps(d), _mm512_abs_ps(limit), _CMP_GE_OQ);
  const __mmask16 toward_zero =
      _kxnor_mask16(_mm512_cmp_ps_mask(mt, mcur, _CMP_GT_OQ), _mm512_cmp_ps_mask(mt, zero, _CMP_GT_OQ));
  const __mmask16 at_zero = _mm512_mask_cmp_ps_mask(back, mt, zero, _CMP_EQ_OQ);
  const __m512i one = _mm512_set1_epi32(1), sign = _mm512_set1_epi32(static_cast<int>(0x80000000u));
  __m512i bits = _mm512_castps_si512(mt);
  bits = _mm512_mask_sub_epi32(bits, _kand_mask16(back, toward_zero), bits, one);
  bits = _mm512_mask_add_epi32(bits, _kandn_mask16(toward_zero, back), bits, one);
  bits = _mm512_mask_or_epi32(bits, at_zero, _mm512_and_si512(_mm512_castps_si512(mcur), sign), one);
  return reinterpret_cast<f16>(_mm512_castsi512_ps(bits));
}
}  // namespace hpcm::solver

#include "cpu/kernel_table.hpp"

namespace hpcm::cpu {

SimdKernels kernels_avx512() { return simd::kernel_table<simd::f16>("avx512"); }

}  // namespace hpcm::cpu
