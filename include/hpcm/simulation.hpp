#pragma once
// The frame pipeline (SPEC §6) over any Backend: it keeps the grab and the anchors as a
// Control and calls Backend::step once per frame (docs/architecture.md, "The seam"):
//   X- <- X;  deform stage (targets, propagate, relax K) while a grab is held, else idle
//   stage (relax K only, never propagate);  velocity layer -> X_{t+1}; boundary clamp;
//   frame-end link restoration (the layer's step can fold cells; docs/solver.md, "No fold").
#include <memory>
#include <string>
#include <vector>

#include "hpcm/backend_factory.hpp"

namespace hpcm {

namespace solver {
class ToolLimitSearch;
}

struct FrameReport {
  int frame = 0;
  bool deform = false;          ///< deformation stage (a grab is held) or idle stage
  float grab_offset = 0;        ///< |tool offset| achieved, lattice units (0 when nothing is held)
  float requested_offset = 0;   ///< |tool offset| the input asked for
  double grab_offset_mm = 0;       ///< grab_offset in millimetres (lattice spacing and direction)
  double requested_offset_mm = 0;  ///< requested_offset in millimetres
  bool tool_limited = false;    ///< the tissue could not follow the tool this far: the pull was limited
  Index restored_links = 0;     ///< links the restoration found outside their box (then restored)
  float restore_violation = 0;  ///< the largest of those violations before restoring
  Index end_folded_cells = 0;  ///< cells the velocity layer folded, unfolded by the frame-end fold guard
  Index end_guard_moved = 0;   ///< elements the fold guard moved (0: the frame end is the velocity layer's)
  Index moved_elements = 0;     ///< elements whose position changed this frame
  Index active_bricks = 0;       ///< bricks that had work this frame (any stage)
  Index active_elements = 0;    ///< elements in those bricks
  float max_link_violation = -1;  ///< after the ChainMail stage; -1 when not measured
  float min_cell_jacobian = -1;   ///< smallest cell corner Jacobian determinant at frame end; -1 when not measured
  Index folded_cells = -1;        ///< cells with a corner determinant <= 0 at frame end; -1 when not measured
  int propagate_sweeps = 0, relax_sweeps = 0;
  bool propagate_converged = true;
  bool restore_converged = true;  ///< false when a restoration pass reached its cap (links may stay outside)
  double chainmail_ms = 0, inertia_ms = 0, snapshot_ms = 0, sim_total_ms = 0;
  PerTissue mean_speed{}, max_speed{};  ///< |X_end(t) - X_end(t-1)| per class, over the body's elements (SPEC §3)
};

/// Largest grab radius, lattice units (along every axis for a radius in millimetres).
inline constexpr float kMaxGrabRadius = 64.0f;

/// Grab radius per lattice axis of a sphere of `radius_mm` millimetres.
Vec3 grab_radii_of_mm(const Model& m, float radius_mm);
/// The rule for a radius given with a grab: [0, kMaxGrabRadius], 0 meaning
/// params.solver.grab_radius. Anything else (negative, NaN, larger) throws Error naming `what`.
void check_grab_radius(float radius, const std::string& what);
/// The rule for a radius in millimetres on lattice `m`: > 0 and at most kMaxGrabRadius lattice
/// units along every axis. Anything else throws Error naming `what`.
void check_grab_radius_mm(const Model& m, float radius_mm, const std::string& what);

struct StepOptions {
  bool speeds = true;               ///< reduce per-tissue speeds (costs the velocity layer's reduction and a
                                    ///< download of every frame-end displacement in each frame with motion: a
                                    ///< frame the fold guard changes takes its speeds from the previous frame's end)
  bool link_violation = false;      ///< measure max link violation over all links (O(N))
  bool cell_jacobian = false;       ///< measure the smallest cell Jacobian determinant at frame end (O(N))
};

class Simulation {
 public:
  Simulation(Model model, Params params, BackendKind backend = BackendKind::Cpu);
  Simulation(Model model, Params params, std::unique_ptr<Backend> backend);
  // The backend keeps a pointer to model(): a Simulation stays where it was made.
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;
  ~Simulation();

  const Model& model() const { return model_; }
  const Params& params() const { return params_; }
  /// Applies new params; rebuilds materials when tissue thresholds or material changed, and tells
  /// the backend what changed (Backend::notify_model_changed).
  void set_params(const Params& p);

  // --- grab tool (SPEC §4) ---
  /// Grabs every element within `radius` (lattice units, rest coordinates) of `centre`;
  /// radius 0 uses params.solver.grab_radius (check_grab_radius). Replaces any current grab.
  void grab(Index centre, float radius = 0);
  /// The same with a radius in millimetres: the elements within radius_mm of the centre
  /// (on an anisotropic lattice an ellipsoid of radius_mm / spacing per axis). radius_mm must
  /// be finite, > 0 and at most kMaxGrabRadius lattice units along every axis.
  void grab_mm(Index centre, float radius_mm);
  /// Moves the tool: grabbed elements go rigidly to (position at grab time + offset). An
  /// offset the tissue cannot follow (the links between the tool and the anchors or the
  /// boundary cannot stretch that far) is limited to the closest one it can: tool_offset()
  /// then differs from requested_offset() and tool_limited() is true.
  void move_tool(Vec3 offset);
  void release();
  bool grabbing() const { return !grabbed_.empty(); }
  Index grab_centre() const { return grab_centre_; }
  Vec3 tool_offset() const { return tool_offset_; }
  Vec3 requested_offset() const { return requested_offset_; }
  bool tool_limited() const { return !(tool_offset_ == requested_offset_); }
  /// Feasible tool offsets of the current grab, per axis [lo, hi] (lattice units; 0 when
  /// nothing is held). The tool's moves search only as far as they need; these run the search
  /// of the whole box.
  Vec3 tool_limit_lo() const;
  Vec3 tool_limit_hi() const;
  const std::vector<Index>& grabbed() const { return grabbed_; }

  /// One frame of the pipeline.
  FrameReport step(const StepOptions& opt = {});
  /// Back to rest (u = 0, V = 0), grab released, frame counter 0.
  void reset();
  int frame() const { return frame_; }

  /// Full state (downloaded from the backend when it changed).
  const State& state();
  /// Displacement from rest u = X - X0 of element i (lattice units).
  Vec3 displacement(Index i) { return backend_->displacement(i); }
  /// Position X0 + u of element i, in double.
  Point3 position(Index i) { return position_of(model_, i, backend_->displacement(i)); }
  /// Direct access to the backend (it may change positions: the cached metrics are dropped).
  Backend& backend() {
    ++positions_version_;
    return *backend_;
  }

 private:
  /// Grabs the elements within the ellipsoid of these per-axis radii (lattice units).
  void grab_within(Index centre, Vec3 radii);
  /// solver.grab_slip: drops from the grab the elements other than `centre` bound to an anchor.
  void let_bound_elements_slip(Index centre);
  void push_fixed();
  void compute_anchors();
  void compute_tool_limit();
  Model model_;
  Params params_;
  std::unique_ptr<Backend> backend_;
  State host_;
  bool host_valid_ = false;
  std::uint64_t host_since_ = 0;  ///< Backend::download_since's stamp of host_
  std::vector<Index> anchors_;
  std::vector<Index> grabbed_;
  std::vector<Vec3> grab_origin_;
  Index grab_centre_ = -1;
  Vec3 tool_offset_{}, requested_offset_{};
  Control control_;  ///< the FIXED set (anchors, then the grab) and its targets, given to every step
  std::unique_ptr<solver::ToolLimitSearch> tool_limit_;  ///< of the current grab; null when none
  std::vector<std::uint8_t> anchored_;  ///< per element: anchored at rest (grabbed elements excluded)
  int frame_ = 0;
  // Integrity metrics of the current positions, kept while no brick had work.
  struct Metric {
    std::uint64_t version = ~std::uint64_t{0};
    float value = 0;
    Index count = 0;
  };
  std::uint64_t positions_version_ = 0;
  Metric link_metric_, jacobian_metric_;
  IncrementalMetrics jacobian_metrics_;  ///< recomputes the cells around what moved
  /// Frame-end displacements on the host (of positions_version_ end_pos_version_): the previous
  /// frame's end, from which the speeds of a frame the fold guard changed are taken.
  std::vector<Vec3> end_pos_, previous_end_;
  std::uint64_t end_pos_since_ = 0, previous_end_since_ = 0;  ///< their download_displacements_since stamps
  std::uint64_t end_pos_version_ = ~std::uint64_t{0};
  /// Downloads the current displacements into end_pos_ unless they are there already.
  const std::vector<Vec3>& frame_end_displacements();
  /// Off only with the environment variable HPCM_SKIP_FRAME_END_RESTORE=1: the pipeline before
  /// the frame-end restoration, whose frame ends can fold (tests and before/after comparisons).
  bool frame_end_restore_ = true;
};

}  // namespace hpcm
