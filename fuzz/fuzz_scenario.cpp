// libFuzzer harness: scenario files (TOML text -> Scenario). Any input must end in a Scenario
// or hpcm::Error; accepted scenarios must round-trip and keep every tool offset finite.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "hpcm/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const hpcm::Scenario s = hpcm::config::parse_scenario(text, "fuzz.toml");
    const hpcm::Scenario again = hpcm::config::parse_scenario(hpcm::config::scenario_to_toml(s), "again.toml");
    if (again.frames != s.frames || again.grabs.size() != s.grabs.size()) __builtin_trap();
    for (const hpcm::GrabAction& g : s.grabs)
      for (int r = 0; r < 64; ++r) {
        const hpcm::Vec3 o = hpcm::path_offset(g, r);
        if (!std::isfinite(o.x) || !std::isfinite(o.y) || !std::isfinite(o.z)) __builtin_trap();
      }
  } catch (const hpcm::Error&) {
  }
  return 0;
}
