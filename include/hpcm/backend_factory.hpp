#pragma once
// Creating backends (library layer hpcm_pipeline: it links the CPU backend and, when built,
// the CUDA backend).
#include <memory>
#include <string>

#include "hpcm/backend.hpp"

namespace hpcm {

/// Creates a backend. Cuda throws hpcm::Error("no CUDA device ...") when none is present, or
/// when hpcm was built without the CUDA backend.
std::unique_ptr<Backend> make_backend(BackendKind k);
/// True when the CUDA backend is compiled in and a device is present; `why` explains if not.
bool cuda_available(std::string* why = nullptr);

}  // namespace hpcm
