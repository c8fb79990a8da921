// Export hook of `hpcm run` (issue 4): the displacement field (mm, NIfTI + NRRD), the deformed
// CT on the input grid (input's format) and the tissue label map with a Slicer colour table.
// Every --export-every N frames and at the end of the run. See docs/slicer.md.
#include <cstdio>
#include <filesystem>

#include "run_options.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::cli {

void add_export_options(CLI::App* cmd, RunOptions& o) {
  cmd->add_option("--export", o.export_dir,
                  "Folder for 3D Slicer exports: displacement field (mm), deformed CT, tissue labels (needs ITK)");
  cmd->add_option("--export-every", o.export_every, "Also export every N frames (0: only at the end)");
}

void ExportSession::write_frame(const std::string& tag, bool final_export) {
#if defined(HPCM_WITH_ITK)
  const std::string dir = o_.export_dir + "/";
  const std::vector<Vec3>& pos = sim_.state().pos;
  io::write_displacement_field(sim_.model(), pos, dir + "displacement_" + tag + ".nii.gz");
  if (final_export) io::write_displacement_field(sim_.model(), pos, dir + "displacement_" + tag + ".nrrd");
  io::write_deformed_volume(original_, sim_.model(), pos, dir + "deformed_" + tag + ext_);
#endif
}

ExportSession::ExportSession(const RunOptions& o, Simulation& sim) : o_(o), sim_(sim) {
  if (o_.export_every < 0)
    throw Error("--export-every " + std::to_string(o_.export_every) + " is out of range: must be >= 0");
  if (o_.export_every > 0 && o_.export_dir.empty()) throw Error("--export-every needs --export DIR");
  if (o_.export_dir.empty()) return;
#if defined(HPCM_WITH_ITK)
  make_output_dir(o_.export_dir, "--export");
  // The input grid (cropped to --roi when given, never down-sampled).
  VolumeSource full = o_.source;
  full.downsample = 1;
  original_ = load_volume(full);
  ext_ = o_.source.input.empty() ? ".nii.gz" : io::volume_extension_for(o_.source.input);
  io::write_label_map(sim_.model(), o_.export_dir + "/labels.nii.gz");
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
  write_frame(tag, false);
#endif
}

void ExportSession::finish() {
#if defined(HPCM_WITH_ITK)
  if (o_.export_dir.empty()) return;
  write_frame("final", true);
  std::printf("exported to %s: displacement_final.nii.gz/.nrrd (mm), deformed_final%s, labels.nii.gz + labels.ctbl\n",
              (o_.export_shown.empty() ? o_.export_dir : o_.export_shown).c_str(), ext_.c_str());
#endif
}

}  // namespace hpcm::cli
