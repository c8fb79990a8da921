// CUDA backend entry points (device detection). The kernels land with the CUDA backend issue.
#include <cuda_runtime.h>

#include <memory>
#include <string>

#include "hpcm/backend.hpp"

namespace hpcm {

bool cuda_device_present(std::string* why) {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess || n == 0) {
    if (why) *why = e != cudaSuccess ? cudaGetErrorString(e) : "no device found";
    return false;
  }
  return true;
}

std::unique_ptr<Backend> make_cuda_backend() {
  throw Error("--backend cuda: the CUDA kernels are not implemented in this build yet");
}

}  // namespace hpcm
