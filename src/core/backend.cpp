#include "hpcm/backend.hpp"

namespace hpcm {

const char* backend_name(BackendKind k) { return k == BackendKind::Cpu ? "cpu" : "cuda"; }

BackendKind parse_backend(const std::string& s, const std::string& what) {
  if (s == "cpu") return BackendKind::Cpu;
  if (s == "cuda") return BackendKind::Cuda;
  throw Error(what + " = '" + s + "' is not one of cpu|cuda");
}

}  // namespace hpcm
