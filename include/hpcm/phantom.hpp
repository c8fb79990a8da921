#pragma once
// The built-in synthetic abdominal phantom (SPEC §9): air around an elliptic body, skin,
// subcutaneous fat, muscle wall, organs, a spine; realistic HU plus seeded noise.
#include <cstdint>

#include "hpcm/volume.hpp"

namespace hpcm {

struct PhantomOptions {
  Int3 dims{128, 128, 75};
  std::uint64_t seed = 1;
  float noise_hu = 12.0f;  ///< standard deviation of the additive noise, [0, 200]
};

/// Deterministic for given options. Spacing keeps a ~400 x 400 x 300 mm field of view.
/// Throws hpcm::Error for dims < 8 on any axis or more than 2^31 elements.
Volume make_phantom(const PhantomOptions& o);

}  // namespace hpcm
