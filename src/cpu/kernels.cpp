#include "cpu/kernels.hpp"

#include <cstdlib>

namespace hpcm::cpu {

bool cpu_has_avx2() { return __builtin_cpu_supports("avx2"); }
bool cpu_has_avx512() {
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq") &&
         __builtin_cpu_supports("avx512bw");
}

SimdKernels select_kernels(const std::string& force) {
  if (force.empty()) return cpu_has_avx512() ? kernels_avx512() : cpu_has_avx2() ? kernels_avx2() : kernels_sse2();
  if (force == "sse2") return kernels_sse2();
  if (force == "avx2") {
    if (!cpu_has_avx2()) throw Error("the AVX2 kernels were requested but this CPU has no AVX2");
    return kernels_avx2();
  }
  if (force == "avx512") {
    if (!cpu_has_avx512()) throw Error("the AVX-512 kernels were requested but this CPU has no AVX-512 (F, VL, DQ, BW)");
    return kernels_avx512();
  }
  throw Error("CPU kernels: '" + force + "' is not one of sse2|avx2|avx512");
}

std::string chosen_kernels(const std::string& force) {
  if (!force.empty()) return force;
  const char* env = std::getenv("HPCM_CPU_KERNELS");
  if (!env || !*env) return {};
  const std::string v = env;
  if (v != "sse2" && v != "avx2" && v != "avx512")
    throw Error("HPCM_CPU_KERNELS='" + v + "' is not one of sse2|avx2|avx512 (unset it to use the best this CPU runs)");
  return v;
}

}  // namespace hpcm::cpu
