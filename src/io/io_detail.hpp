#pragma once
// Internals of hpcm::io shared by its two translation units and the tests (tests/io).
// Plain C++: no ITK type appears here.
#include <array>
#include <string>
#include <vector>

#include "hpcm/model.hpp"
#include "hpcm/volume.hpp"

namespace hpcm::io::detail {

/// Air value (HU) for output voxels whose rest position lies outside the input.
inline constexpr float kAirHU = -1000.0f;

enum class Format { Unknown, Nifti, NiftiGz, Nrrd, Nhdr, Mha, Mhd };
Format format_of(const std::string& path);  ///< from the (lower-cased) extension
const char* format_name(Format f);          ///< "NIfTI", "NRRD", "MetaImage", ...
std::string extension_of(Format f);         ///< ".nii.gz", ...

/// Geometry of an image in file index order (ITK conventions: LPS physical space,
/// direction row-major, column a = direction of index axis a).
struct Geometry {
  Int3 dims;
  std::array<double, 3> spacing{1, 1, 1};
  std::array<double, 3> origin{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
};

/// For each LPS axis p (0 = L, 1 = P, 2 = S): the file index axis that runs closest to it and
/// whether it runs backwards (a permutation; greedy on the largest |direction| entries).
struct AxisMap {
  std::array<int, 3> src{0, 1, 2};
  std::array<bool, 3> flip{false, false, false};
};
AxisMap lps_axis_map(const std::array<double, 9>& direction);

/// Permutes/flips a scalar buffer in file index order into LPS index order (SPEC §2). The
/// physical position of every voxel is unchanged; direction, spacing and origin follow.
Volume reorient_to_lps(const float* data, const Geometry& g);

/// 3x3 helpers (row-major).
std::array<double, 9> mat_inverse(const std::array<double, 9>& m);

/// Inverse-mapping resample of the deformed lattice onto the original grid (SPEC/issue 4):
/// output voxel q -> lattice point x; rest position X solves X = x - u(X) (fixed-point,
/// trilinear u); HU = trilinear sample of `original` at X's physical position, kAirHU where
/// that lies outside `original`. `pos` are lattice positions (pos.size() == m.size()).
std::vector<float> resample_deformed(const Volume& original, const Model& m, const std::vector<Vec3>& pos,
                                     int max_iterations = 12);

/// Lattice displacement pos - rest converted to millimetres in LPS physical space:
/// u_mm = direction * (spacing (.) u). Interleaved xyz, pos.size() * 3 floats.
std::vector<float> displacement_mm(const Model& m, const std::vector<Vec3>& pos);

/// Any image read without reorientation or conversion to HU (for tests and diagnostics).
struct RawImage {
  Geometry geometry;
  int dimensions = 0;
  int components = 0;
  std::string component_type;  ///< ITK's name: "float", "short", "unsigned_char", ...
  std::string pixel_type;      ///< ITK's name: "scalar", "vector", "rgb", ...
  std::vector<float> data;     ///< interleaved components, file index order
};
RawImage read_raw_image(const std::string& path);

/// Bytes of memory available to this process (MemAvailable of /proc/meminfo, else physical).
std::size_t available_memory_bytes();

/// Message text of a byte count: "1.23 GB".
std::string format_bytes(double bytes);

}  // namespace hpcm::io::detail
