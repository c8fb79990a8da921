// hpcm bench: placeholder until the benchmark command lands (CUDA backend issue).
#include "cli_common.hpp"
namespace hpcm::cli {
void register_bench(CLI::App&) {}
}  // namespace hpcm::cli
