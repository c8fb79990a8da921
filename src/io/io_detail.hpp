#pragma once
// Internals of hpcm::io shared by its two translation units and the tests (tests/io).
// Plain C++: no ITK type appears here.
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "hpcm/io.hpp"
#include "hpcm/model.hpp"
#include "hpcm/volume.hpp"

namespace hpcm::io::detail {

/// Air value (HU) for output voxels whose rest position lies outside the input.
inline constexpr float kAirHU = -1000.0f;

/// Fixed-point iterations the deformed CT's inverse mapping allows per voxel.
inline constexpr int kInverseMappingIterations = 12;
/// Newton steps allowed after them for voxels still above the tolerance.
inline constexpr int kInverseMappingNewtonIterations = 20;

enum class Format { Unknown, Nifti, NiftiGz, Nrrd, Nhdr, Mha, Mhd };
Format format_of(const std::string& path);  ///< from the (lower-cased) extension
const char* format_name(Format f);          ///< "NIfTI", "NRRD", "MetaImage", ...
std::string extension_of(Format f);         ///< ".nii.gz", ...

/// Geometry of an image in file index order (ITK conventions: LPS physical space,
/// direction row-major, column a = direction of index axis a).
using Geometry = Grid;

/// Calls f(lattice_index, stored_index) for every voxel of a grid of `stored_dims` laid in LPS
/// order by `order` (lattice_index runs x fastest in LPS order). One loop serves both
/// directions of the permutation; z planes run in parallel.
template <class F>
void for_each_lattice_voxel(Int3 stored_dims, const IndexOrder& order, F&& f) {
  const int sd[3] = {stored_dims.x, stored_dims.y, stored_dims.z};
  const std::int64_t sstride[3] = {1, sd[0], static_cast<std::int64_t>(sd[0]) * sd[1]};
  int ld[3];
  std::int64_t step[3];
  std::int64_t start = 0;
  for (int p = 0; p < 3; ++p) {
    const int a = order.axis[static_cast<std::size_t>(p)];
    ld[p] = sd[a];
    step[p] = order.reversed[static_cast<std::size_t>(p)] ? -sstride[a] : sstride[a];
    if (order.reversed[static_cast<std::size_t>(p)]) start += static_cast<std::int64_t>(sd[a] - 1) * sstride[a];
  }
#pragma omp parallel for schedule(static)
  for (int z = 0; z < ld[2]; ++z)
    for (int y = 0; y < ld[1]; ++y) {
      std::int64_t s = start + z * step[2] + y * step[1];
      std::int64_t l = (static_cast<std::int64_t>(z) * ld[1] + y) * ld[0];
      for (int x = 0; x < ld[0]; ++x, s += step[0], ++l) f(l, s);
    }
}

/// The grid `g` (stored order) as the lattice sees it: dims, spacing, origin, direction in LPS
/// order. Every voxel keeps its physical position.
Grid grid_in_lps_order(const Grid& g, const IndexOrder& order);

/// Throws unless `m` is the lattice of `in` (dims and geometry), naming `what`.
void check_model_matches(const Input& in, const Model& m, const std::string& what);

/// 3x3 helpers (row-major).
std::array<double, 9> mat_inverse(const std::array<double, 9>& m);
double mat_det(const std::array<double, 9>& m);
/// Index -> physical millimetres: direction * diag(spacing) (column a = step along index axis a).
std::array<double, 9> index_to_physical_matrix(const std::array<double, 9>& dir, const std::array<double, 3>& sp);

/// Receives one output voxel of the inverse mapping: its linear index in the output grid (first
/// index fastest), its rest position X in lattice index units and q0, the same position as a
/// continuous voxel index of the output grid (snapped to a voxel centre within 1e-4). Called from several threads (distinct voxels).
using RestPositionVisitor = std::function<void(std::int64_t voxel, const double* X, const double* q0)>;
/// The inverse mapping of the deformed lattice onto `original` (a grid in any index order): for
/// each voxel at x the rest position X solving X + u(X) = x (see resample_deformed), handed to
/// `visit`. One pass serves every export that needs it (deformed CT, labels, pull-back field).
InverseMappingStats for_each_rest_position(const Grid& original, const Model& m, const std::vector<Vec3>& disp,
                                           int max_iterations, int newton_iterations, const RestPositionVisitor& visit);
/// Trilinear HU of `original` at continuous voxel index q; kAirHU beyond half a voxel outside.
float sample_trilinear(const Volume& original, const double q[3]);
/// Linear index of the voxel nearest to continuous index q in a grid of `dims`; -1 beyond half
/// a voxel outside.
std::int64_t nearest_voxel(Int3 dims, const double q[3]);

/// Inverse-mapping resample of the deformed lattice onto the grid of `original` (any index
/// order):
/// output voxel q -> lattice point x; rest position X solves X = x - u(X) (trilinear u); HU = trilinear sample of `original` at X's physical position, kAirHU where
/// that lies outside `original`. `disp` are the elements' displacements from rest, lattice units (disp.size() == m.size()).
/// Up to `max_iterations` fixed-point steps from X = x, then, where the residual is still above
/// kInverseMappingToleranceMm, up to `newton_iterations` Newton steps (with step halving).
/// `stats` (optional) receives how well the inverse mapping converged.
std::vector<float> resample_deformed(const Volume& original, const Model& m, const std::vector<Vec3>& disp,
                                     int max_iterations = kInverseMappingIterations,
                                     int newton_iterations = kInverseMappingNewtonIterations,
                                     InverseMappingStats* stats = nullptr);

/// Lattice displacement u converted to millimetres in LPS physical space:
/// u_mm = direction * (spacing (.) u). Interleaved xyz, disp.size() * 3 floats.
std::vector<float> displacement_mm(const Model& m, const std::vector<Vec3>& disp);

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
