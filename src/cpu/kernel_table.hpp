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
