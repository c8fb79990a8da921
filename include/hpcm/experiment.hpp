#pragma once
// The paper's experiment as a reproducible protocol (SPEC §7): conditions A/B/C on identical
// input, tissue-wise speed curves, Table 2 (initial/peak/AUC), Table 3 (stage times), and the
// behaviour checks of SPEC §8.1-8.5, 8.7 and 8.8, each held, failed or not applicable.
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "hpcm/folded_frames.hpp"
#include "hpcm/scenario.hpp"

namespace hpcm {

/// Per-class sums in double: added over every counted element of many frames.
using TissueSums = std::array<double, kTissueCount>;

struct ConditionResult {
  DampingMode mode = DampingMode::None;
  std::string label;                      ///< "A", "B", "C"
  std::vector<FrameReport> frames;        ///< every frame of the scenario
  std::vector<Vec3> centre_displacement;  ///< grab-centre displacement from rest at the end of each frame
  std::vector<Vec3> centre_velocity;      ///< its velocity state V at the end of each frame (0 while held, and under A)
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
  FoldedFrames folded;                    ///< the frames that fold, protocol and settle frames
  // The tool: the largest offset the protocol asked for and the largest the tissue allowed.
  float max_requested_offset = 0, max_achieved_offset = 0;
  int first_limited_frame = -1;           ///< first frame the pull was limited (-1: never)
  std::vector<LimitedPull> limited_pulls; ///< each stretch of limited frames, per grab and keyframe segment
  // SPEC §8.8: each class's speeds over the recorded frames, split by the rest-position distance
  // from the grab centre (FarFieldSplit).
  TissueSums far_speed_sum{}, total_speed_sum{};
};

/// SPEC §8.8: how much of each class's AUC after release is carried by the far field, the body
/// elements whose rest position lies farther than `distance` lattice units from the grab
/// centre's rest position. Per recorded frame it adds each counted element's speed
/// |X_end(t) - X_end(t-1)| to its class total and, when far, to its class's far total; the far
/// share is far total / total over all recorded frames (= far part of the AUC / the AUC, since
/// both divide by the same class count every frame). Computed on the host from the frame-end
/// positions, so it is the same code for every backend.
class FarFieldSplit {
 public:
  static constexpr float kDefaultDistance = 40.0f;
  FarFieldSplit(const Model& model, Index centre, float distance = kDefaultDistance);
  /// One frame: displacements at the end of the previous frame and of this one (model-sized).
  void add_frame(const std::vector<Vec3>& before, const std::vector<Vec3>& after);
  const TissueSums& far_sum() const { return far_; }
  const TissueSums& total_sum() const { return total_; }
  float distance() const { return distance_; }

 private:
  std::vector<std::int8_t> code_;  ///< per element: -1 not counted, else tissue + kTissueCount when far
  float distance_;
  TissueSums far_{}, total_{};
};

/// Far share of class t (far / total); -1 when the class did not move (total 0: no share).
double far_field_share(const TissueSums& far_sum, const TissueSums& total_sum, int t);

/// SPEC §8: a check is held, failed, or not applicable (computed and reported, but the input is
/// outside what the clause is required on, e.g. a lattice below 64 along its two longest axes).
enum class CheckStatus { Held, Failed, NotApplicable };
const char* check_status_name(CheckStatus s);  ///< "held", "failed", "not_applicable"

struct Check {
  std::string name;         ///< e.g. "A_no_overshoot"
  std::string spec;         ///< SPEC clause, e.g. "8.1"
  CheckStatus status = CheckStatus::Failed;
  double value = 0;         ///< the figure (+inf for a ratio over 0; written as JSON null)
  double threshold = 0;
  std::string description;  ///< what value and threshold mean
  std::string reason;       ///< why not applicable (empty otherwise)
  bool holds() const { return status == CheckStatus::Held; }
  bool failed() const { return status == CheckStatus::Failed; }
  bool applicable() const { return status != CheckStatus::NotApplicable; }
};

/// SPEC §8: the motion checks (8.1-8.4, 8.8) are held on lattices with at least this many
/// elements along each of the two longest axes; 8.2 also needs an achieved pull of kMinSwingPull.
inline constexpr int kMotionLatticeMin = 64;
inline constexpr float kMinSwingPull = 0.5f;
/// Empty when `dims` is held to the motion checks, else the reason ("lattice 48×48×32 below 64 ...").
std::string motion_checks_not_applicable(Int3 dims);

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
  float far_field_distance = FarFieldSplit::kDefaultDistance;  ///< SPEC §8.8, lattice units
  /// No check failed (held or not applicable).
  bool all_hold() const;
  int count(CheckStatus s) const;
};

ExperimentResult run_experiment(const Model& model, const Params& params, const ExperimentOptions& opt = {});

/// Table 2 of one condition over frames [release, release + count).
void table2(const std::vector<FrameReport>& frames, int release, int count, PerTissue& initial,
            PerTissue& peak, PerTissue& auc);

}  // namespace hpcm
