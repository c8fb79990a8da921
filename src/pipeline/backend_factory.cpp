#include "hpcm/backend_factory.hpp"

#include "cpu/cpu_backend.hpp"
#if defined(HPCM_HAVE_CUDA)
#include "cuda/cuda_backend.hpp"
#endif

namespace hpcm {

bool cuda_available(std::string* why) {
#if defined(HPCM_HAVE_CUDA)
  return cuda_device_present(why);
#else
  if (why) *why = "hpcm was built without the CUDA backend (no CUDA compiler found at build time)";
  return false;
#endif
}

std::unique_ptr<Backend> make_backend(BackendKind k) {
  if (k == BackendKind::Cpu) return std::make_unique<cpu::CpuBackend>();
  std::string why;
  if (!cuda_available(&why)) throw Error("--backend cuda: no CUDA device: " + why);
#if defined(HPCM_HAVE_CUDA)
  return make_cuda_backend();
#else
  return nullptr;
#endif
}

}  // namespace hpcm
