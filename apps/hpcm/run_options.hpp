#pragma once
// Options of `hpcm run` and the export hook that the IO layer fills in.
#include <string>

#include "cli_common.hpp"

namespace hpcm::cli {

struct RunOptions {
  VolumeSource source;
  std::string dynamics;
  std::string params;
  std::string scenario;
  int frames = -1000000;  ///< sentinel: not given
  std::string backend = "cpu";
  std::string out;
  bool no_link_check = false;
  // Export (hpcm::io): every N frames and at the end.
  std::string export_dir;
  int export_every = 0;
  bool frames_given() const { return frames != -1000000; }
};

/// Adds --export DIR / --export-every N (no-op without ITK).
void add_export_options(CLI::App* cmd, RunOptions& o);

/// Writes the exports of a run: every N frames and at the end (no-op without --export).
class ExportSession {
 public:
  ExportSession(const RunOptions& o, Simulation& sim);
  void after_frame(int frame, int total);
  void finish();

 private:
  void write_frame(const std::string& tag, bool final_export);
  const RunOptions& o_;
  Simulation& sim_;
#if defined(HPCM_WITH_ITK)
  io::Input input_;     ///< the input on its own grid, and how the lattice lies on it
#endif
};

std::string frames_csv_header();
std::string frames_csv_row(const FrameReport& r);
Params resolve_params(const RunOptions& o);
Scenario resolve_scenario(const RunOptions& o);

}  // namespace hpcm::cli
