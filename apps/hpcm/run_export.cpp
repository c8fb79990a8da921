// Export hook of `hpcm run`: the displacement field (mm, NIfTI + NRRD) and the tissue label map
// on the input's grid coarsened by --downsample, and the deformed CT on the input's grid, all in
// the input file's own index order and geometry. Every --export-every N frames and at the end.
// Each export is checked (the field's Jacobian determinant, the inverse mapping's residual) and
// recorded with its grids in DIR/export.json. See docs/io.md and docs/slicer.md.
#include <cstdio>
#include <filesystem>
#include <set>

#include "run_options.hpp"

namespace hpcm::cli {

void add_export_options(CLI::App* cmd, RunOptions& o) {
  cmd->add_option("--export", o.export_dir,
                  "Folder for exports on the input's grid: displacement field (mm), deformed CT, tissue labels, "
                  "export.json (needs ITK)");
  cmd->add_option("--export-every", o.export_every, "Also export every N frames (0: only at the end)");
  cmd->add_option("--warp-labels", o.warp_labels,
                  "Label map on the input's grid (NIfTI/NRRD/MHA, integer type) to deform with every export, by "
                  "nearest label: warped_<name>_<tag><ext> (repeatable; needs --export)")
      ->allow_extra_args(false);
  cmd->add_flag("--strict", o.strict,
                "Exit with an error (after writing every file) when a frame folds (a cell corner determinant <= 0 at "
                "frame end), an exported displacement field folds or the deformed CT's inverse mapping did not "
                "converge");
}

#if defined(HPCM_WITH_ITK)
namespace {

nlohmann::json int3_json(Int3 v) { return {v.x, v.y, v.z}; }

nlohmann::json grid_json(const io::Grid& g) {
  return {{"shape", int3_json(g.dims)},
          {"spacing", g.spacing},
          {"origin", g.origin},
          {"direction", g.direction}};
}

nlohmann::json file_json(const std::string& path, const io::Grid& g, const std::string& content, int components) {
  nlohmann::json j = grid_json(g);
  j["file"] = std::filesystem::path(path).filename().string();
  j["content"] = content;
  j["components"] = components;
  return j;
}

/// One export's entry of export.json: its files with their grids and the integrity figures.
nlohmann::json export_json(const io::Input& in, const io::ExportFiles& f, const std::string& tag, int frames_done,
                           const std::vector<std::string>& warp_sources) {
  const io::ExportIntegrity& ig = f.integrity;
  nlohmann::json j;
  j["tag"] = tag;
  j["frames_done"] = frames_done;
  j["frame"] = frames_done - 1;  // the frames.csv row of the positions exported
  const std::string field =
      "forward (modelling, ToParent) displacement u = X - X0, millimetres, LPS components: rest position X0 moves "
      "to X; resampling tools need displacement_pullback_<tag> instead";
  j["files"].push_back(file_json(f.displacement_nifti, in.lattice_grid, field, 3));
  if (!f.displacement_nrrd.empty()) j["files"].push_back(file_json(f.displacement_nrrd, in.lattice_grid, field, 3));
  const io::Grid grid = io::grid_of(in.stored);
  j["files"].push_back(file_json(f.deformed, grid, "deformed CT, HU", 1));
  const std::string pullback =
      "pull-back (resampling, FromParent) displacement v = X - x, millimetres, LPS components: the deformed CT at "
      "x is the input at x + v(x) (for plastimatch convert --xf, ITK resampling, Slicer); NOT the forward field";
  j["files"].push_back(file_json(f.pullback_nifti, grid, pullback, 3));
  if (!f.pullback_nrrd.empty()) j["files"].push_back(file_json(f.pullback_nrrd, grid, pullback, 3));
  j["files"].push_back(file_json(f.labels_deformed, grid,
                                 "deformed tissue class (0 air, 1 skin_fat, 2 muscle_organ, 3 bone), nearest label "
                                 "through the deformed CT's inverse mapping",
                                 1));
  for (std::size_t k = 0; k < f.warped_labels.size(); ++k) {
    nlohmann::json w = file_json(f.warped_labels[k], grid,
                                 "label map deformed by nearest label through the deformed CT's inverse mapping "
                                 "(0 outside the input)",
                                 1);
    w["source"] = warp_sources[k];
    j["files"].push_back(w);
  }
  j["displacement_jacobian"] = {
      {"computed_on", std::filesystem::path(f.displacement_nifti).filename().string()},
      {"method", "det(I + du/dp) at the 8 corners of every grid cell, from the differences along the cell's edges "
                 "(forward at low corners, backward at high ones), p in millimetres"},
      {"cells_checked", ig.field.cells},
      {"folded_cells", ig.field.folded_cells},
      {"min_det", ig.field.cells > 0 ? nlohmann::json(ig.field.min_det) : nlohmann::json(nullptr)},
      {"min_det_cell", ig.field.cells > 0 ? nlohmann::json(int3_json(ig.field.min_det_cell)) : nlohmann::json(nullptr)},
      {"fold_free", ig.fold_free()}};
  j["deformed_inverse_mapping"] = {{"file", std::filesystem::path(f.deformed).filename().string()},
                                   {"voxels", ig.deformed.voxels},
                                   {"unconverged_voxels", ig.deformed.unconverged},
                                   {"max_residual_mm", ig.deformed.max_residual_mm},
                                   {"worst_voxel", int3_json(ig.deformed.worst_voxel)},
                                   {"tolerance_mm", ig.deformed.tolerance_mm},
                                   {"fixed_point_iterations", ig.deformed.max_iterations},
                                   {"newton_iterations", ig.deformed.newton_iterations},
                                   {"converged", ig.converged()}};
  j["clean"] = ig.clean();
  j["problems"] = io::export_problems(f);
  return j;
}

}  // namespace
#endif

void ExportSession::write_frame(const std::string& tag, int frames_done, bool final_export) {
#if defined(HPCM_WITH_ITK)
  const io::ExportFiles f =
      io::export_frame(input_, sim_.model(), sim_.state().disp, o_.export_dir, tag, final_export, warp_labels_);
  const std::string shown = o_.export_shown.empty() ? o_.export_dir : o_.export_shown;
  for (const std::string& p : io::export_problems(f)) {
    std::fprintf(stderr, "hpcm: warning: export %s (frame %d) in %s: %s\n", tag.c_str(), frames_done - 1, shown.c_str(),
                 p.c_str());
    problems_.push_back(p);
  }
  sidecar_["exports"].push_back(export_json(input_, f, tag, frames_done, o_.warp_labels));
  bool clean = true;
  for (const auto& e : sidecar_["exports"]) clean = clean && e["clean"].get<bool>();
  sidecar_["all_clean"] = clean;
  write_json_file(o_.export_dir + "/export.json", sidecar_);
#endif
}

ExportSession::ExportSession(const RunOptions& o, Simulation& sim) : o_(o), sim_(sim) {
  if (o_.export_every < 0)
    throw Error("--export-every " + std::to_string(o_.export_every) + " is out of range: must be >= 0");
  if (o_.export_every > 0 && o_.export_dir.empty()) throw Error("--export-every needs --export DIR");
  if (!o_.warp_labels.empty() && o_.export_dir.empty()) throw Error("--warp-labels needs --export DIR");
  if (o_.export_dir.empty()) return;
#if defined(HPCM_WITH_ITK)
  input_ = load_input(o_.source);  // the same input the lattice came from, with its own grid
  // Every label map is read and checked against the input's grid before anything is written.
  std::set<std::string> names;
  for (const std::string& path : o_.warp_labels) {
    const std::string name = io::warped_label_name(path, "final");
    if (!names.insert(name).second)
      throw Error("--warp-labels " + path + ": another label map has the same file name; its deformed copy (" + name +
                  ") would overwrite the other's");
    warp_labels_.push_back(io::label_map_on_input_grid(io::read_label_map(path), input_));
  }
  make_output_dir(o_.export_dir, "--export");
  const std::string labels = o_.export_dir + "/labels.nii.gz";
  io::write_label_map(input_, sim_.model(), labels);
  sidecar_["input"] = input_.source;
  sidecar_["roi"] = {{"lo", {input_.roi.lo.x, input_.roi.lo.y, input_.roi.lo.z}},
                     {"hi", {input_.roi.hi.x, input_.roi.hi.y, input_.roi.hi.z}}};
  sidecar_["downsample"] = input_.downsample;
  // Which header fields gave the input's grid (NIfTI: sform, qform or pixdim, nibabel's rule).
  if (const std::string g = io::nifti_geometry_source(o_.source.input); !g.empty()) sidecar_["input_geometry"] = g;
  sidecar_["conventions"] =
      "shape, spacing, origin and direction are the file's own (ITK): LPS millimetres, direction row-major with "
      "column a the direction of index axis a; frame is the frames.csv row whose end positions were exported";
  sidecar_["labels"] = file_json(labels, input_.lattice_grid, "tissue class (0 air, 1 skin_fat, 2 muscle_organ, 3 bone)", 1);
  sidecar_["exports"] = nlohmann::json::array();
#else
  throw Error("--export " + o_.export_dir + ": hpcm was built without ITK, exports are not available");
#endif
}

void ExportSession::after_frame(int frame, int total) {
#if defined(HPCM_WITH_ITK)
  const int done = frame + 1;
  if (o_.export_dir.empty() || o_.export_every <= 0 || done % o_.export_every != 0) return;
  char tag[32];
  std::snprintf(tag, sizeof tag, "%04d", done);
  write_frame(tag, done, false);
#endif
}

void ExportSession::finish(int frames) {
#if defined(HPCM_WITH_ITK)
  if (o_.export_dir.empty()) return;
  write_frame("final", frames, true);
  const auto& last = sidecar_["exports"].back();
  const auto& jac = last["displacement_jacobian"];
  const auto& inv = last["deformed_inverse_mapping"];
  std::printf("exported to %s: displacement_final.nii.gz/.nrrd (forward, mm), displacement_pullback_final.nii.gz/.nrrd "
              "(pull-back, mm), deformed_final%s, labels.nii.gz + labels_deformed_final.nii.gz (+ .ctbl)%s, export.json\n",
              (o_.export_shown.empty() ? o_.export_dir : o_.export_shown).c_str(), io::deformed_extension(input_).c_str(),
              warp_labels_.empty() ? "" : (", " + std::to_string(warp_labels_.size()) + " warped_*_final label map(s)").c_str());
  std::printf("  field: %lld of %lld cells folded (smallest Jacobian determinant %s); deformed CT: %lld of %lld voxels "
              "not converged (largest residual %.3g mm)\n",
              jac["folded_cells"].get<long long>(), jac["cells_checked"].get<long long>(),
              jac["min_det"].is_null() ? "n/a, no cells" : std::to_string(jac["min_det"].get<double>()).c_str(),
              inv["unconverged_voxels"].get<long long>(), inv["voxels"].get<long long>(),
              inv["max_residual_mm"].get<double>());
#else
  (void)frames;
#endif
}

}  // namespace hpcm::cli
