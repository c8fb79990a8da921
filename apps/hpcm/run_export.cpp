// Export hook of `hpcm run`: the displacement field (mm, NIfTI + NRRD) and the tissue label map
// on the input's grid coarsened by --downsample, and the deformed CT on the input's grid, all in
// the input file's own index order and geometry. Every --export-every N frames and at the end.
// See docs/io.md and docs/slicer.md.
#include <cstdio>
#include <filesystem>

#include "run_options.hpp"

namespace hpcm::cli {

void add_export_options(CLI::App* cmd, RunOptions& o) {
  cmd->add_option("--export", o.export_dir,
                  "Folder for exports on the input's grid: displacement field (mm), deformed CT, tissue labels (needs ITK)");
  cmd->add_option("--export-every", o.export_every, "Also export every N frames (0: only at the end)");
}

void ExportSession::write_frame(const std::string& tag, bool final_export) {
#if defined(HPCM_WITH_ITK)
  io::export_frame(input_, sim_.model(), sim_.state().pos, o_.export_dir, tag, final_export);
#endif
}

ExportSession::ExportSession(const RunOptions& o, Simulation& sim) : o_(o), sim_(sim) {
  if (o_.export_every < 0)
    throw Error("--export-every " + std::to_string(o_.export_every) + " is out of range: must be >= 0");
  if (o_.export_every > 0 && o_.export_dir.empty()) throw Error("--export-every needs --export DIR");
  if (o_.export_dir.empty()) return;
#if defined(HPCM_WITH_ITK)
  make_output_dir(o_.export_dir, "--export");
  input_ = load_input(o_.source);  // the same input the lattice came from, with its own grid
  io::write_label_map(input_, sim_.model(), o_.export_dir + "/labels.nii.gz");
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
              (o_.export_shown.empty() ? o_.export_dir : o_.export_shown).c_str(), io::deformed_extension(input_).c_str());
#endif
}

}  // namespace hpcm::cli
