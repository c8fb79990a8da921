// hpcm::io, the export pieces without ITK: checking that a model belongs to an input, the
// displacement field on the input's grid, its fold check, and the files of one export.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
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

std::vector<float> displacement_on_input_grid(const Input& in, const Model& m, const std::vector<Vec3>& disp) {
  detail::check_model_matches(in, m, "displacement field");
  const std::vector<float> lattice_mm = detail::displacement_mm(m, disp);
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

namespace {
std::string grid_text(const Grid& g) {
  char buf[320];
  std::snprintf(buf, sizeof buf, "%dx%dx%d voxels, spacing %g,%g,%g mm, origin %g,%g,%g mm, direction %g,%g,%g,%g,%g,%g,%g,%g,%g",
                g.dims.x, g.dims.y, g.dims.z, g.spacing[0], g.spacing[1], g.spacing[2], g.origin[0], g.origin[1],
                g.origin[2], g.direction[0], g.direction[1], g.direction[2], g.direction[3], g.direction[4],
                g.direction[5], g.direction[6], g.direction[7], g.direction[8]);
  return buf;
}

bool same_grid(const Grid& a, const Grid& b) {
  if (!(a.dims == b.dims)) return false;
  for (int k = 0; k < 3; ++k)
    if (std::abs(a.spacing[k] - b.spacing[k]) > 1e-4 || std::abs(a.origin[k] - b.origin[k]) > 1e-4) return false;
  for (int k = 0; k < 9; ++k)
    if (std::abs(a.direction[k] - b.direction[k]) > 1e-6) return false;
  return true;
}

// The label map cut to box [lo, hi) of its own indices (what --roi does to the CT).
LabelMap crop(const LabelMap& map, const Box& box) {
  LabelMap out = map;
  const Int3 n{box.hi.x - box.lo.x, box.hi.y - box.lo.y, box.hi.z - box.lo.z};
  out.grid.dims = n;
  const int lo[3] = {box.lo.x, box.lo.y, box.lo.z};
  for (int r = 0; r < 3; ++r)
    for (int a = 0; a < 3; ++a) out.grid.origin[r] += map.grid.direction[r * 3 + a] * map.grid.spacing[a] * lo[a];
  out.data.assign(out.grid.size() * map.bytes, 0);
  const std::size_t row = static_cast<std::size_t>(n.x) * map.bytes;
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y) {
      const std::size_t src = (box.lo.x + static_cast<std::size_t>(map.grid.dims.x) *
                                              (box.lo.y + y + static_cast<std::size_t>(map.grid.dims.y) * (box.lo.z + z))) *
                              map.bytes;
      std::memcpy(out.data.data() + (static_cast<std::size_t>(z) * n.y + y) * row, map.data.data() + src, row);
    }
  return out;
}
}  // namespace

LabelMap label_map_on_input_grid(LabelMap map, const Input& in) {
  const Grid target = grid_of(in.stored);
  if (same_grid(map.grid, target)) return map;
  // An --roi run: a label map on the whole input file's grid is cropped like the CT.
  const Int3 d = map.grid.dims;
  if (d.x >= in.roi.hi.x && d.y >= in.roi.hi.y && d.z >= in.roi.hi.z && !(d == target.dims)) {
    const LabelMap cropped = crop(map, in.roi);
    if (same_grid(cropped.grid, target)) return cropped;
  }
  throw Error(map.source + ": label map on another grid than the input " + in.source + ": label map " +
              grid_text(map.grid) + "; input" + (in.roi.lo == Int3{} && in.roi.hi == target.dims ? "" : " (cropped to the roi)") +
              " " + grid_text(target) + " (a label map must be on the input's own grid)");
}

std::string warped_label_name(const std::string& label_path, const std::string& tag) {
  const std::string file = std::filesystem::path(label_path).filename().string();
  const std::string ext = detail::extension_of(detail::format_of(file));
  const std::string stem = file.substr(0, file.size() - ext.size());
  return "warped_" + stem + "_" + tag + ext;
}

DeformedOnInputGrid deform_on_input_grid(const Input& in, const Model& m, const std::vector<Vec3>& disp,
                                         const std::vector<LabelMap>& labels) {
  detail::check_model_matches(in, m, "deformed CT");
  if (static_cast<Index>(m.tissue.size()) != m.size())
    throw Error("deformed labels: the model has " + std::to_string(m.tissue.size()) + " tissue labels for " +
                std::to_string(m.size()) + " elements");
  DeformedOnInputGrid d;
  d.grid = grid_of(in.stored);
  const std::size_t n = d.grid.size();
  for (const LabelMap& l : labels)
    if (!same_grid(l.grid, d.grid) || l.data.size() != n * static_cast<std::size_t>(l.bytes))
      throw Error(l.source + ": label map on another grid than the input " + in.source + ": label map " +
                  grid_text(l.grid) + "; input " + grid_text(d.grid));
  d.hu.resize(n);
  d.pullback_mm.resize(3 * n);
  d.classes.resize(n);
  for (const LabelMap& l : labels) {
    LabelMap out = l;
    out.data.assign(l.data.size(), 0);
    d.labels.push_back(std::move(out));
  }
  const std::array<double, 9> A = detail::index_to_physical_matrix(d.grid.direction, d.grid.spacing);
  const Int3 dims = d.grid.dims;
  d.stats = detail::for_each_rest_position(
      d.grid, m, disp, detail::kInverseMappingIterations, detail::kInverseMappingNewtonIterations,
      [&](std::int64_t voxel, const double* X, const double* q0) {
        d.hu[voxel] = detail::sample_trilinear(in.stored, q0);
        // Pull-back v = X - x in millimetres: where each output voxel takes its value from.
        const double q[3] = {double(voxel % dims.x), double((voxel / dims.x) % dims.y),
                             double(voxel / (static_cast<std::int64_t>(dims.x) * dims.y))};
        for (int r = 0; r < 3; ++r) {
          double v = 0;
          for (int a = 0; a < 3; ++a) v += A[r * 3 + a] * (q0[a] - q[a]);
          d.pullback_mm[3 * voxel + r] = static_cast<float>(v);
        }
        // Nearest label: labels are never averaged (no label is invented).
        const std::int64_t element = detail::nearest_voxel(m.dims, X);
        d.classes[voxel] = element < 0 ? 0 : m.counted(element) ? m.tissue[element] : kOutsideLabel;
        const std::int64_t source = detail::nearest_voxel(dims, q0);
        for (std::size_t k = 0; k < labels.size(); ++k) {
          const std::size_t b = static_cast<std::size_t>(labels[k].bytes);
          if (source >= 0) std::memcpy(d.labels[k].data.data() + voxel * b, labels[k].data.data() + source * b, b);
        }
      });
  return d;
}

ExportFiles export_frame(const Input& in, const Model& m, const std::vector<Vec3>& disp, const std::string& dir,
                         const std::string& tag, bool nrrd_field, const std::vector<LabelMap>& labels) {
  const std::filesystem::path d(dir);
  ExportFiles f;
  f.displacement_nifti = (d / ("displacement_" + tag + ".nii.gz")).string();
  f.integrity.field = displacement_jacobian(in.lattice_grid, displacement_on_input_grid(in, m, disp));
  write_displacement_field(in, m, disp, f.displacement_nifti);
  if (nrrd_field) {
    f.displacement_nrrd = (d / ("displacement_" + tag + ".nrrd")).string();
    write_displacement_field(in, m, disp, f.displacement_nrrd);
  }
  f.deformed = (d / ("deformed_" + tag + deformed_extension(in))).string();
  const DeformedOnInputGrid def = deform_on_input_grid(in, m, disp, labels);
  Volume deformed = in.stored;
  deformed.hu = def.hu;
  write_volume(deformed, f.deformed);
  f.integrity.deformed = def.stats;
  f.pullback_nifti = (d / ("displacement_pullback_" + tag + ".nii.gz")).string();
  write_pullback_field(def.grid, def.pullback_mm, f.pullback_nifti);
  if (nrrd_field) {
    f.pullback_nrrd = (d / ("displacement_pullback_" + tag + ".nrrd")).string();
    write_pullback_field(def.grid, def.pullback_mm, f.pullback_nrrd);
  }
  f.labels_deformed = (d / ("labels_deformed_" + tag + ".nii.gz")).string();
  write_class_labels(def.grid, def.classes, f.labels_deformed);
  for (const LabelMap& l : def.labels) {
    f.warped_labels.push_back((d / warped_label_name(l.source, tag)).string());
    write_label_values(l, f.warped_labels.back());
  }
  return f;
}

}  // namespace hpcm::io
