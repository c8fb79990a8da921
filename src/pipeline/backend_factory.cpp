#include <memory>

#include "pipeline/cpu_backend.hpp"

namespace hpcm {

#if defined(HPCM_HAVE_CUDA)
// Implemented in src/cuda (compiled only when a CUDA compiler is found).
std::unique_ptr<Backend> make_cuda_backend();
bool cuda_device_present(std::string* why);
#endif

const char* backend_name(BackendKind k) { return k == BackendKind::Cpu ? "cpu" : "cuda"; }

BackendKind parse_backend(const std::string& s, const std::string& what) {
  if (s == "cpu") return BackendKind::Cpu;
  if (s == "cuda") return BackendKind::Cuda;
  throw Error(what + " = '" + s + "' is not one of cpu|cuda");
}

bool cuda_available(std::string* why) {
#if defined(HPCM_HAVE_CUDA)
  return cuda_device_present(why);
#else
  if (why) *why = "hpcm was built without the CUDA backend (no CUDA compiler found at build time)";
  return false;
#endif
}

std::unique_ptr<Backend> make_backend(BackendKind k) {
  if (k == BackendKind::Cpu) return std::make_unique<CpuBackend>();
  std::string why;
  if (!cuda_available(&why)) throw Error("--backend cuda: no CUDA device: " + why);
#if defined(HPCM_HAVE_CUDA)
  return make_cuda_backend();
#else
  return nullptr;
#endif
}

}  // namespace hpcm
