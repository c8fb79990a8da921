#pragma once
// Options of `hpcm run` and the export hook that the IO layer fills in.
#include <optional>
#include <string>

#include "cli_common.hpp"

namespace hpcm::cli {

struct RunOptions {
  VolumeSource source;
  std::string dynamics;
  std::string params;
  std::string scenario;
  std::optional<int> frames;  ///< not given: the scenario's length
  std::string backend = "cpu";
  std::string out;
  bool no_link_check = false;
  // Export (hpcm::io): every N frames and at the end.
  std::string export_dir;     ///< where the exports are written (the staging folder during a run)
  std::string export_shown;   ///< the --export folder as given, for messages (empty: export_dir)
  int export_every = 0;
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
/// One frames.csv row; throws hpcm::Error naming the frame and column when a value is not finite.
std::string frames_csv_row(const FrameReport& r);
Params resolve_params(const RunOptions& o);
Scenario resolve_scenario(const RunOptions& o);

/// "scenario FILE" / "the paper protocol": how messages name the scenario of `path`.
std::string scenario_label(const std::string& path);
/// Rethrows an error raised while playing scenario frame `frame` (-1: while preparing it),
/// prefixed with the scenario, the grab and the keyframe segment active at that frame.
[[noreturn]] void rethrow_in_scenario(const Error& e, const Scenario& sc, const std::string& label, int frame);

}  // namespace hpcm::cli
