// libFuzzer harness: parameter files (TOML text -> validated Params). Any input must end in
// Params or hpcm::Error; a crash, a hang, UB or another exception is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include "hpcm/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const hpcm::Params p = hpcm::config::parse_params(text, "fuzz.toml");
    // What was accepted must write out and read back to the same values.
    if (!(hpcm::config::parse_params(hpcm::config::params_to_toml(p), "again.toml") == p)) __builtin_trap();
  } catch (const hpcm::Error&) {
  }
  return 0;
}
