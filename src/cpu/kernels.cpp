#include "cpu/kernels.hpp"

namespace hpcm::cpu {

SimdKernels select_kernels(const std::string& force) {
  const bool avx2 = __builtin_cpu_supports("avx2");
  if (force == "sse2" || (force.empty() && !avx2)) return kernels_sse2();
  if (!force.empty() && force != "avx2") throw Error("CPU kernels: '" + force + "' is not one of sse2|avx2");
  if (!avx2) throw Error("the AVX2 kernels were requested but this CPU has no AVX2");
  return kernels_avx2();
}

}  // namespace hpcm::cpu
