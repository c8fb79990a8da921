#pragma once
// The table of SIMD kernels of one vector width. Included last by each simd_*.cpp, after its
// vector type and the helpers of simd.hpp are defined for its instruction set; each file
// instantiates it for its own vector type only.
#include "cpu/kernels.hpp"
#include "cpu/layer_simd.hpp"
#include "cpu/link_check_simd.hpp"
#include "cpu/relax_simd.hpp"

namespace hpcm::cpu::simd {

template <class V>
SimdKernels kernel_table(const char* name) {
  SimdKernels k;
  k.relax = [](const RelaxContext& c, const RelaxRun& r) { return relax_run<V>(c, r); };
  k.relax_step = [](const float* s, const float* sw, const float* cur, float omega, float* out, int n) {
    constexpr int N = sizeof(V) / sizeof(float);
    const V om = splat<V>(omega), limit_factor = splat<V>(0.5f * (2.0f + omega));  // as relax_span
    for (int i = 0; i < n; i += N) {
      V a = splat<V>(0.0f), b = splat<V>(1.0f), c = splat<V>(0.0f);  // lanes past n: a zero step
      for (int l = 0; l < N && i + l < n; ++l) {
        a[l] = s[i + l];
        b[l] = sw[i + l];
        c[l] = cur[i + l];
      }
      const V t = relax_step(a, b, c, om, limit_factor);
      for (int l = 0; l < N && i + l < n; ++l) out[i + l] = t[l];
    }
  };
  k.layer = [](Storage& st, const dynamics::LayerConstants& lc, const LayerRow& row, SpeedStats* sp) {
    layer_row<V>(st, lc, row, sp);
  };
  k.link_check = [](const Storage& st, const solver::Wall& w, int h, int y, int z, int j0, int j1, std::vector<int>& out) {
    link_check_row<V>(st, w, h, y, z, j0, j1, out);
  };
  k.name = name;
  return k;
}

}  // namespace hpcm::cpu::simd
