// hpcm::io, the export pieces without ITK: checking that a model belongs to an input, the
// displacement field on the input's grid, its fold check, and the files of one export.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <filesystem>

#include "hpcm/io.hpp"
#include "io_detail.hpp"

namespace hpcm::io {
namespace detail {

namespace {
std::string dims_text(Int3 d) { return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z); }
}  // namespace

void check_model_matches(const Input& in, const Model& m, const std::string& what) {
  const Volume& l = in.lattice;
  bool same = m.dims == l.dims;
  for (int a = 0; a < 3 && same; ++a)
    same = std::abs(m.spacing[a] - l.spacing[a]) <= 1e-6 * l.spacing[a] && std::abs(m.origin[a] - l.origin[a]) <= 1e-6 * (1.0 + std::abs(l.origin[a]));
  for (int k = 0; k < 9 && same; ++k) same = std::abs(m.direction[k] - l.direction[k]) <= 1e-9;
  if (!same)
    throw Error(what + ": the model's lattice (" + dims_text(m.dims) + ") is not the lattice of " + in.source + " (" +
                dims_text(l.dims) + ", down-sampled by " + std::to_string(in.downsample) +
                "): build the model from this input's lattice volume");
}

}  // namespace detail

std::vector<float> displacement_on_input_grid(const Input& in, const Model& m, const std::vector<Vec3>& pos) {
  detail::check_model_matches(in, m, "displacement field");
  const std::vector<float> lattice_mm = detail::displacement_mm(m, pos);
  if (in.order.identity()) return lattice_mm;
  std::vector<float> out(lattice_mm.size());
  detail::for_each_lattice_voxel(in.lattice_grid.dims, in.order, [&](std::int64_t l, std::int64_t s) {
    for (int c = 0; c < 3; ++c) out[3 * s + c] = lattice_mm[3 * l + c];  // components are physical: unchanged
  });
  return out;
}

FieldJacobianStats displacement_jacobian(const Grid& g, const std::vector<float>& u) {
  if (u.size() != 3 * g.size())
    throw Error("displacement field check: " + std::to_string(u.size()) + " values for a grid of " +
                std::to_string(g.size()) + " voxels x 3 components");
  const int n[3] = {g.dims.x, g.dims.y, g.dims.z};
  const std::array<double, 9> A = detail::index_to_physical_matrix(g.direction, g.spacing);
  const double det_a = detail::mat_det(A);
  if (!(std::abs(det_a) > 0)) throw Error("displacement field check: the grid's direction matrix is singular");
  FieldJacobianStats st;
  if (n[0] < 2 || n[1] < 2 || n[2] < 2) return st;
  st.cells = static_cast<Index>(n[0] - 1) * (n[1] - 1) * (n[2] - 1);
  const std::int64_t stride[3] = {1, n[0], static_cast<std::int64_t>(n[0]) * n[1]};
  // Per plane of cells, combined in plane order afterwards (independent of the thread count).
  const std::size_t planes = static_cast<std::size_t>(n[2] - 1);
  std::vector<double> plane_min(planes, std::numeric_limits<double>::infinity());
  std::vector<Int3> plane_at(planes);
  std::vector<Index> plane_folded(planes, 0);
#pragma omp parallel for schedule(static)
  for (int z = 0; z < n[2] - 1; ++z)
    for (int y = 0; y < n[1] - 1; ++y)
      for (int x = 0; x < n[0] - 1; ++x) {
        const std::int64_t cell = x + stride[1] * y + stride[2] * z;
        bool cell_folded = false;
        for (int corner = 0; corner < 8; ++corner) {
          const std::int64_t at = cell + ((corner & 1) ? stride[0] : 0) + ((corner & 2) ? stride[1] : 0) +
                                  ((corner & 4) ? stride[2] : 0);
          // Edge a at this corner, oriented along +a: index-to-mm column plus the change of u.
          std::array<double, 9> e;  // row-major: column a = edge a
          for (int a = 0; a < 3; ++a) {
            const bool high = (corner >> a) & 1;
            const std::int64_t lo = high ? at - stride[a] : at, hi = high ? at : at + stride[a];
            for (int r = 0; r < 3; ++r) e[r * 3 + a] = A[r * 3 + a] + double(u[3 * hi + r]) - double(u[3 * lo + r]);
          }
          const double det = detail::mat_det(e) / det_a;
          if (det < plane_min[z]) {
            plane_min[z] = det;
            plane_at[z] = {x, y, z};
          }
          cell_folded = cell_folded || !(det > 0);
        }
        plane_folded[z] += cell_folded ? 1 : 0;
      }
  st.min_det = std::numeric_limits<double>::infinity();
  for (std::size_t z = 0; z < planes; ++z) {
    st.folded_cells += plane_folded[z];
    if (plane_min[z] < st.min_det) {
      st.min_det = plane_min[z];
      st.min_det_cell = plane_at[z];
    }
  }
  return st;
}

std::vector<std::string> export_problems(const ExportFiles& f) {
  std::vector<std::string> out;
  const auto name = [](const std::string& p) { return std::filesystem::path(p).filename().string(); };
  char buf[512];
  const FieldJacobianStats& j = f.integrity.field;
  if (j.folded_cells > 0) {
    std::string files = name(f.displacement_nifti);
    if (!f.displacement_nrrd.empty()) files += " and " + name(f.displacement_nrrd);
    std::snprintf(buf, sizeof buf,
                  "the displacement field folds: %lld of %lld cells have a Jacobian determinant <= 0 (smallest %.6g, "
                  "in the cell at voxel %d,%d,%d)",
                  static_cast<long long>(j.folded_cells), static_cast<long long>(j.cells), j.min_det, j.min_det_cell.x,
                  j.min_det_cell.y, j.min_det_cell.z);
    out.push_back(files + ": " + buf);
  }
  const InverseMappingStats& d = f.integrity.deformed;
  if (d.unconverged > 0) {
    std::snprintf(buf, sizeof buf,
                  "the inverse mapping did not converge for %lld of %lld voxels (largest residual %.3g mm at voxel "
                  "%d,%d,%d; tolerance %.3g mm after %d fixed-point and %d Newton iterations): their HU may come "
                  "from the wrong place",
                  static_cast<long long>(d.unconverged), static_cast<long long>(d.voxels), d.max_residual_mm,
                  d.worst_voxel.x, d.worst_voxel.y, d.worst_voxel.z, d.tolerance_mm, d.max_iterations,
                  d.newton_iterations);
    out.push_back(name(f.deformed) + ": " + buf);
  }
  return out;
}

std::string deformed_extension(const Input& in) {
  std::error_code ec;
  if (!in.source.empty() && std::filesystem::exists(in.source, ec)) return volume_extension_for(in.source);
  return ".nii.gz";
}

ExportFiles export_frame(const Input& in, const Model& m, const std::vector<Vec3>& pos, const std::string& dir,
                         const std::string& tag, bool nrrd_field) {
  const std::filesystem::path d(dir);
  ExportFiles f;
  f.displacement_nifti = (d / ("displacement_" + tag + ".nii.gz")).string();
  f.integrity.field = displacement_jacobian(in.lattice_grid, displacement_on_input_grid(in, m, pos));
  write_displacement_field(in, m, pos, f.displacement_nifti);
  if (nrrd_field) {
    f.displacement_nrrd = (d / ("displacement_" + tag + ".nrrd")).string();
    write_displacement_field(in, m, pos, f.displacement_nrrd);
  }
  f.deformed = (d / ("deformed_" + tag + deformed_extension(in))).string();
  f.integrity.deformed = write_deformed_volume(in, m, pos, f.deformed);
  return f;
}

}  // namespace hpcm::io
