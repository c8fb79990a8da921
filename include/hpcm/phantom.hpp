#pragma once
// The built-in synthetic abdominal phantom (SPEC §9): air around an elliptic body, skin,
// subcutaneous fat, muscle wall, organs, a spine; realistic HU plus seeded noise. Variants
// change the anatomy the defaults were not tuned on (docs/tuning.md has what each shows).
#include <cstdint>
#include <string>
#include <vector>

#include "hpcm/volume.hpp"

namespace hpcm {

enum class PhantomVariant {
  Standard,     ///< the default abdomen
  ThinTissue,   ///< lean: ~2 elements of skin + fat everywhere, a sternum-like bone plate under the anterior midline
  ThickFat,     ///< obese: subcutaneous fat ~75 mm (at least 9 elements) thick
  AirPockets,   ///< more bowel gas, and a gas pocket right behind the anterior muscle wall at mid-height
  Table,        ///< the body lies on a dense CT table (carbon-fibre shells, foam core) that flattens its back
  Anisotropic,  ///< thick-slice CT: voxel spacing ratio 0.8 : 0.8 : 5 (x : y : z), slices are slab means
};

/// "standard", "thin-tissue", "thick-fat", "air-pockets", "table", "anisotropic".
const char* phantom_variant_name(PhantomVariant v);
/// Inverse of phantom_variant_name; throws hpcm::Error naming `option`, the value and the valid names.
PhantomVariant parse_phantom_variant(const std::string& name, const std::string& option);
/// Every variant, in declaration order.
std::vector<PhantomVariant> all_phantom_variants();

struct PhantomOptions {
  Int3 dims{128, 128, 75};
  std::uint64_t seed = 1;
  float noise_hu = 12.0f;  ///< standard deviation of the additive noise, [0, 200]
  PhantomVariant variant = PhantomVariant::Standard;
};

/// Deterministic for given options. Spacing keeps a ~400 x 400 x 300 mm field of view (the
/// anisotropic variant: 400 x 400 mm in-plane, slices 6.25 times thicker than the in-plane spacing).
/// Throws hpcm::Error for dims < 8 on any axis or more than 2^31 elements.
Volume make_phantom(const PhantomOptions& o);

}  // namespace hpcm
