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
    const V om = splat<V>(omega);
    for (int i = 0; i < n; i += N) {
      V a = splat<V>(0.0f), b = splat<V>(1.0f), c = splat<V>(0.0f);  // lanes past n: a zero step
      for (int l = 0; l < N && i + l < n; ++l) {
        a[l] = s[i + l];
        b[l] = sw[i + l];
        c[l] = cur[i + l];
      }
      const V t = solver::relax_coordinate(c, a / b, om);  // as relax_span (solver::ProposalSum::target)
      for (int l = 0; l < N && i + l < n; ++l) out[i + l] = t[l];
    }
  };
  k.link_rules = [](const LinkRuleLanes& io, bool axial, int side, int axis, int n) {
    constexpr int N = sizeof(V) / sizeof(float);
    for (int i = 0; i < n; i += N) {
      V tau = splat<V>(0.5f), c = splat<V>(0.0f), d[3] = {splat<V>(0.0f), splat<V>(0.0f), splat<V>(0.0f)};
      for (int l = 0; l < N && i + l < n; ++l) {
        tau[l] = io.tau[i + l];
        c[l] = io.c[i + l];
        for (int b = 0; b < 3; ++b) d[b][l] = io.d[b][i + l];
      }
      const LinkBox<V> box = box_from_tau(tau);
      V lo, hi;
      link_interval(c, box, axial, side, lo, hi);
      const V excess = link_axis_excess(d[0], box, axial), violation = link_violation(d, box, axis);
      for (int l = 0; l < N && i + l < n; ++l) {
        io.min_stretch[i + l] = box.min_stretch[l];
        io.max_stretch[i + l] = box.max_stretch[l];
        io.shear[i + l] = box.shear[l];
        io.lo[i + l] = lo[l];
        io.hi[i + l] = hi[l];
        io.excess[i + l] = excess[l];
        io.violation[i + l] = violation[l];
      }
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
