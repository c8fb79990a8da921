#pragma once
// Four tissue classes from HU with half-open thresholds t1 < t2 < t3 (SPEC §3).
#include <array>
#include <cstdint>
#include <string>

#include "hpcm/types.hpp"

namespace hpcm {

enum class Tissue : std::uint8_t { Air = 0, SkinFat = 1, MuscleOrgan = 2, Bone = 3 };
inline constexpr int kTissueCount = 4;
/// Per-class values, indexed by static_cast<int>(Tissue).
using PerTissue = std::array<float, kTissueCount>;

/// "air", "skin_fat", "muscle_organ", "bone": the names used in files and columns.
const char* tissue_name(Tissue t);
const char* tissue_name(int t);

struct TissueThresholds {
  float t1 = -1000.0f;  ///< air | skin&fat
  float t2 = 25.0f;     ///< skin&fat | muscle&organ
  float t3 = 375.0f;    ///< muscle&organ | bone

  /// Throws hpcm::Error unless finite and strictly increasing.
  void validate() const;
  HPCM_HD Tissue classify(float hu) const {
    return hu < t1 ? Tissue::Air : hu < t2 ? Tissue::SkinFat : hu < t3 ? Tissue::MuscleOrgan : Tissue::Bone;
  }
  /// Alternative preset for noisy scanners: air below -500 (so outside air is air),
  /// soft tissue split at 0, bone from 200 (cancellous bone counts as bone).
  static TissueThresholds robust_preset() { return {-500.0f, 0.0f, 200.0f}; }
  friend bool operator==(const TissueThresholds&, const TissueThresholds&) = default;
};

}  // namespace hpcm
