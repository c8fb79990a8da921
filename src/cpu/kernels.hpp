#pragma once
// The CPU's SIMD kernels and their run-time choice: AVX2 where the CPU has it, SSE2 (every
// x86-64 CPU) otherwise. Both give the same bits as the scalar rules they mirror.
#include <string>

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

struct SimdKernels {
  RelaxRunKernel relax = nullptr;
  LayerRowKernel layer = nullptr;
  const char* name = "";  ///< "avx2" or "sse2"
};

SimdKernels kernels_sse2();
SimdKernels kernels_avx2();
/// The best kernels this CPU runs; `force` ("sse2", "avx2", or empty) is for tests and
/// benchmarks. A forced AVX2 on a CPU without it throws hpcm::Error.
SimdKernels select_kernels(const std::string& force);

}  // namespace hpcm::cpu
