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
}  // namespace hpcm::cpu::simd

#include "cpu/layer_simd.hpp"
#include "cpu/link_check_simd.hpp"
#include "cpu/relax_simd.hpp"

namespace hpcm::cpu {

SimdKernels kernels_avx2() {
  SimdKernels k;
  k.relax = [](const RelaxContext& c, const RelaxRun& r) { return simd::relax_run<simd::f8>(c, r); };
  k.layer = [](Storage& st, const dynamics::LayerConstants& lc, const LayerRow& row, SpeedStats* sp) {
    simd::layer_row<simd::f8>(st, lc, row, sp);
  };
  k.link_check = [](const Storage& st, const solver::Wall& w, int h, int y, int z, int j0, int j1, std::vector<int>& out) {
    return simd::link_check_row<simd::f8>(st, w, h, y, z, j0, j1, out);
  };
  k.name = "avx2";
  return k;
}

}  // namespace hpcm::cpu
