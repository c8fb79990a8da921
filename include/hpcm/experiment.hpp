#pragma once
// The paper's experiment as a reproducible protocol (SPEC §7): conditions A/B/C on identical
// input, tissue-wise speed curves, Table 2 (initial/peak/AUC), Table 3 (stage times), and the
// behaviour checks of SPEC §8.1-8.5.
#include <functional>
#include <string>
#include <vector>

#include "hpcm/scenario.hpp"

namespace hpcm {

struct ConditionResult {
  DampingMode mode = DampingMode::None;
  std::string label;                      ///< "A", "B", "C"
  std::vector<FrameReport> frames;        ///< every frame of the scenario
  std::vector<Vec3> centre_track;         ///< grab-centre position at the end of each frame
  Vec3 centre_rest{};                     ///< its rest position
  PerTissue initial{}, peak{}, auc{};     ///< Table 2 over the recorded frames after release
  double chainmail_ms = 0, inertia_ms = 0, snapshot_ms = 0, sim_total_ms = 0;  ///< means per frame
  // Long-run checks (SPEC §8.5)
  int settle_frames = 0;                  ///< idle frames run after the scenario
  float settle_max_speed = -1;            ///< largest element speed in the last settle frame
  bool finite = true;                     ///< no NaN/Inf in positions or velocities, ever
  float max_boundary_excess = 0;          ///< largest coordinate beyond [-m, N-1+m] (0 = within)
  float max_bone_velocity = 0;            ///< |V| max over bone elements at the end
  // Integrity (SPEC §8.7), over every frame: protocol and settle frames.
  float max_link_violation = 0;           ///< largest link violation after any ChainMail stage
  float min_cell_jacobian = 1;            ///< smallest cell corner determinant at any frame end
  Index max_folded_cells = 0;             ///< most folded cells at any frame end
  // The tool: the largest offset the protocol asked for and the largest the tissue allowed.
  float max_requested_offset = 0, max_achieved_offset = 0;
  int first_limited_frame = -1;           ///< first frame the pull was limited (-1: never)
  std::vector<LimitedPull> limited_pulls; ///< each stretch of limited frames, per grab and keyframe segment
};

struct Check {
  std::string name;         ///< e.g. "A_no_overshoot"
  std::string spec;         ///< SPEC clause, e.g. "8.1"
  bool holds = false;
  double value = 0;
  double threshold = 0;
  std::string description;  ///< what value and threshold mean
};

struct ExperimentOptions {
  Scenario scenario = Scenario::paper_protocol();
  int settle_frames = 2000;     ///< idle frames after the scenario for SPEC §8.5
  BackendKind backend = BackendKind::Cpu;
  /// Called after each frame: (condition index 0..2, frames done, frames total).
  std::function<void(int, int, int)> progress;
};

struct ExperimentResult {
  Params params;                 ///< full parameter set used (mode per condition overrides)
  Int3 dims;
  Index elements = 0;
  BodySummary body;              ///< the elements the statistics and motion checks count (SPEC §3)
  Index grab_centre = -1;
  int release_frame = 0;         ///< first frame after release
  int recorded_frames = 0;       ///< frames after release that Table 2 covers
  std::vector<ConditionResult> conditions;  ///< A, B, C
  std::vector<Check> checks;
  bool all_hold() const;
};

ExperimentResult run_experiment(const Model& model, const Params& params, const ExperimentOptions& opt = {});

/// Table 2 of one condition over frames [release, release + count).
void table2(const std::vector<FrameReport>& frames, int release, int count, PerTissue& initial,
            PerTissue& peak, PerTissue& auc);

}  // namespace hpcm
