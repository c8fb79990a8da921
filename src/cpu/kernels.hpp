#pragma once
// The CPU's SIMD kernels and their run-time choice: AVX-512 where the CPU has it, else AVX2,
// else SSE2 (every x86-64 CPU). All give the same bits as the scalar rules they mirror.
#include <string>
#include <vector>

#include "cpu/relax.hpp"
#include "cpu/storage.hpp"
#include "dynamics/velocity_update.hpp"
#include "hpcm/stats.hpp"

namespace hpcm::cpu {

/// Elements [j0, j1) of half h of row (y, z), for the velocity layer. Element j's brick column
/// is (j - col_base) / col_width: elements of a column with col_asleep set get no dynamics
/// this frame (as FIXED elements); the layer sets col_velocity when the element carries
/// velocity afterwards, col_moved when it moved it (X_{t+1} != X+), and raises col_speed to
/// the element's |V| before the clamp.
struct LayerRow {
  int h, y, z, j0, j1;
  const std::uint8_t* col_asleep;
  std::uint8_t* col_velocity;
  std::uint8_t* col_moved;
  float* col_speed;
  int col_base, col_width;
};
/// The velocity layer (dynamics::velocity_update) over one row; adds each element's speed
/// |X_{t+1} - X-| to `speeds` in element order when non-null.
using LayerRowKernel = void (*)(Storage& st, const dynamics::LayerConstants& k, const LayerRow& row, SpeedStats* speeds);

/// The link check's vector filter over elements [j0, j1) of half h of row (y, z): appends the
/// elements that may have a violated +x/+y/+z link or lie outside the wall to `flagged`.
using LinkRowKernel = void (*)(const Storage& st, const solver::Wall& wall, int h, int y, int z, int j0, int j1,
                              std::vector<int>& flagged);

/// The relaxation's step, solver::relax_coordinate(cur, s / sw, omega), on n lanes through this
/// width's instantiation of the rule (the one the relaxation kernel calls): lets tests hold
/// every path to the float rule on chosen values (steps a few float steps long, signed zeros,
/// denormals).
using RelaxStepKernel = void (*)(const float* s, const float* sw, const float* cur, float omega, float* out, int n);

/// The link rules (hpcm/material.hpp, core/link_box.hpp) on n lanes, through this width's
/// instantiation (the one the relaxation and link-check kernels call). Inputs per lane: the
/// link's tolerance tau, a neighbour coordinate c, a link's displacement differences d[3].
/// Outputs per lane: box_from_tau(tau); link_interval(c, box, axial, side) as [lo, hi];
/// link_axis_excess(d[0], box, axial); link_violation(d, box, axis).
struct LinkRuleLanes {
  const float* tau;
  const float* c;
  const float* d[3];
  float *min_stretch, *max_stretch, *shear, *lo, *hi, *excess, *violation;
};
using LinkRulesKernel = void (*)(const LinkRuleLanes& io, bool axial, int side, int axis, int n);

struct SimdKernels {
  RelaxRunKernel relax = nullptr;
  RelaxStepKernel relax_step = nullptr;
  LinkRulesKernel link_rules = nullptr;
  LayerRowKernel layer = nullptr;
  LinkRowKernel link_check = nullptr;
  const char* name = "";  ///< "avx512", "avx2" or "sse2"
};

SimdKernels kernels_sse2();
SimdKernels kernels_avx2();
SimdKernels kernels_avx512();
/// Whether this CPU runs the AVX2 / AVX-512 kernels.
bool cpu_has_avx2();
bool cpu_has_avx512();
/// The best kernels this CPU runs; `force` ("sse2", "avx2", "avx512", or empty) is for tests
/// and benchmarks. Forcing kernels this CPU cannot run throws hpcm::Error.
SimdKernels select_kernels(const std::string& force);
/// `force` if not empty, else the value of HPCM_CPU_KERNELS (throws hpcm::Error naming the
/// variable when it is set to something other than sse2|avx2|avx512), else empty.
std::string chosen_kernels(const std::string& force);

}  // namespace hpcm::cpu
