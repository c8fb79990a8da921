#pragma once
// Entry points of the CUDA backend (target hpcm_cuda), for the backend factory.
#include <memory>
#include <string>

#include "hpcm/backend.hpp"

namespace hpcm {

std::unique_ptr<Backend> make_cuda_backend();
/// True when a CUDA device that can run this build's kernels is present; `why` explains if not.
bool cuda_device_present(std::string* why);

}  // namespace hpcm
