#pragma once
// A CT volume in Hounsfield units with its physical geometry, in LPS index order
// (x: right->left, y: anterior->posterior, z: inferior->superior).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "hpcm/types.hpp"

namespace hpcm {

struct Volume {
  Int3 dims;                                   ///< voxels per axis
  std::array<double, 3> spacing{1, 1, 1};      ///< mm per voxel along each index axis
  std::array<double, 3> origin{0, 0, 0};       ///< mm, physical position of voxel (0,0,0), LPS
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major 3x3, column a = axis a
  std::vector<float> hu;                       ///< HU, x fastest
  /// The body on this grid (SPEC §3), 1 per body voxel, 0 outside; empty when it was not
  /// searched. Set by whoever knows it for this very grid (the IO layer on the lattice, the
  /// phantom generator); crop() and downsample() leave it empty (a new grid).
  std::vector<std::uint8_t> body;
  std::string body_method;                     ///< how `body` was found, for the reports

  std::size_t size() const { return static_cast<std::size_t>(dims.x) * dims.y * dims.z; }
  Index index(int x, int y, int z) const { return x + static_cast<Index>(dims.x) * (y + static_cast<Index>(dims.y) * z); }
  float at(int x, int y, int z) const { return hu[static_cast<std::size_t>(index(x, y, z))]; }
  /// Physical position (mm) of a continuous index position.
  std::array<double, 3> index_to_physical(double i, double j, double k) const;
};

/// Throws hpcm::Error if dims are not positive, values not finite, spacing not positive.
void validate_volume(const Volume& v, const std::string& what);

/// Integer down-sampling by block mean of HU over complete f x f x f blocks, in the volume's own
/// index order: dims become floor(dims / f), spacing f * spacing, and element (0,0,0) sits at the
/// centre of the first block (input index (f-1)/2), so every element is at the centre of the
/// voxels it averages. The last dims % f voxels of an axis (fewer than f) belong to no block and
/// are left out. factor must be in [1, min(dims)].
Volume downsample(const Volume& v, int factor);

/// Crop to voxel box [lo, hi) (hi exclusive); geometry follows (origin shifts).
Volume crop(const Volume& v, Int3 lo, Int3 hi);

}  // namespace hpcm
