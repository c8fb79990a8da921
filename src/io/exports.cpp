// hpcm::io, the export pieces without ITK: checking that a model belongs to an input, the
// displacement field on the input's grid, and the files of one export.
#include <cmath>
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
  write_displacement_field(in, m, pos, f.displacement_nifti);
  if (nrrd_field) {
    f.displacement_nrrd = (d / ("displacement_" + tag + ".nrrd")).string();
    write_displacement_field(in, m, pos, f.displacement_nrrd);
  }
  f.deformed = (d / ("deformed_" + tag + deformed_extension(in))).string();
  write_deformed_volume(in, m, pos, f.deformed);
  return f;
}

}  // namespace hpcm::io
