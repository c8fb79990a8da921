#pragma once
// Options of `hpcm run` and the export hook that the IO layer fills in.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

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
  bool strict = false;        ///< exit non-zero when a frame or an export folds or an inverse mapping did not converge
  std::vector<std::string> warp_labels;  ///< label maps on the input's grid, deformed with every export
};

/// Adds --export DIR / --export-every N / --strict (no-op without ITK).
void add_export_options(CLI::App* cmd, RunOptions& o);

/// Writes the exports of a run: every N frames and at the end (no-op without --export), each
/// checked (fold-free field, converged inverse mapping) and recorded in DIR/export.json.
class ExportSession {
 public:
  ExportSession(const RunOptions& o, Simulation& sim);
  void after_frame(int frame, int total);
  /// The final export, after `frames` frames.
  void finish(int frames);
  /// Problems found in any export ("FILE: what"), for --strict; empty when every export is clean.
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  void write_frame(const std::string& tag, int frames_done, bool final_export);
  const RunOptions& o_;
  Simulation& sim_;
  std::vector<std::string> problems_;
  nlohmann::json sidecar_;  ///< export.json, rewritten after every export
#if defined(HPCM_WITH_ITK)
  io::Input input_;     ///< the input on its own grid, and how the lattice lies on it
  std::vector<io::LabelMap> warp_labels_;  ///< --warp-labels, on input_.stored's grid
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
