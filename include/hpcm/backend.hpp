#pragma once
// The backend seam (docs/architecture.md, "The seam"): a backend holds one state (device
// memory on CUDA) and steps it one whole frame at a time, step(in, out, control, request), in
// SPEC §6 order. The order is written once, here (Backend::step, src/core/backend.cpp); the
// CPU (src/cpu) and the CUDA backend (src/cuda) implement its stages from the shared rules of
// src/solver and src/dynamics, and a clock for its named phases. backend_factory.hpp creates
// them.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hpcm/state.hpp"
#include "hpcm/stats.hpp"

namespace hpcm {

/// Device-side figures for benchmarks (hpcm bench). `available` is false on the CPU backend.
struct DeviceProbe {
  bool available = false;
  std::string device;              ///< device name and compute capability
  std::size_t device_bytes = 0;    ///< device memory the backend holds (before the probe)
  double layer_ms = 0;             ///< one fused velocity-layer pass over every element (median)
  double layer_bytes = 0;          ///< bytes that pass reads + writes
  double copy_ms = 0;              ///< one device-to-device copy of the positions (median)
  double copy_bytes = 0;           ///< bytes the copy reads + writes
  double layer_gbs() const { return layer_ms > 0 ? layer_bytes / (layer_ms * 1e6) : 0; }
  double copy_gbs() const { return copy_ms > 0 ? copy_bytes / (copy_ms * 1e6) : 0; }
};

/// What a frame is driven by (Newton's Control): the FIXED set, each element with its target
/// (displacement from rest) and flags (kGrabbed, kAnchor), and whether the frame is a
/// deformation frame (a grab is held: the wave propagates) or an idle one. Every change of the
/// FIXED set gives the control a new revision(): a backend installs a set once, not per frame.
class Control {
 public:
  Control() = default;
  Control(std::vector<Index> fixed, std::vector<Vec3> targets, std::vector<std::uint8_t> flags, bool deform = true) {
    set_fixed(std::move(fixed), std::move(targets), std::move(flags));
    deform_ = deform;
  }
  /// Replaces the FIXED set. A duplicate element takes its last entry.
  void set_fixed(std::vector<Index> fixed, std::vector<Vec3> targets, std::vector<std::uint8_t> flags);
  void set_deform(bool deform) { deform_ = deform; }

  const std::vector<Index>& fixed() const { return fixed_; }
  const std::vector<Vec3>& targets() const { return targets_; }
  const std::vector<std::uint8_t>& flags() const { return flags_; }
  bool deform() const { return deform_; }
  /// Unique over every Control of the process (never 0): equal revisions mean the same set.
  std::uint64_t revision() const { return revision_; }

  /// Throws Error naming the first bad entry and its valid range: the three lists differ in
  /// length, an element outside [0, m.size() - 1], a flag outside {0, kGrabbed, kAnchor,
  /// kGrabbed | kAnchor}, a target that is not finite. Backends validate before they change
  /// anything, so a refused control leaves the old set in force.
  void validate(const Model& m) const;

 private:
  std::vector<Index> fixed_;
  std::vector<Vec3> targets_;
  std::vector<std::uint8_t> flags_;
  bool deform_ = false;
  std::uint64_t revision_ = 0;  ///< 0: the empty set of a default Control (set_fixed gives a new one)
};

/// What changed in the model or the parameters (flags for Backend::notify_model_changed).
enum ModelChange : unsigned {
  kMaterialsChanged = 1,  ///< tissue classes, tolerances, link table (rebuild_materials)
  kAnchorsChanged = 2,    ///< the anchor mode: every brick is looked at again
  kParamsChanged = 4,     ///< dynamics, relaxation settings, boundary margin, brick size
};

/// The named, timed phases of a frame (FrameReport: Snapshot = snapshot, ChainMail = chainmail +
/// frame_end, Inertia = inertia, SimTotal = their sum).
enum class Phase : int { Snapshot, ChainMail, Inertia, FrameEnd };
inline constexpr int kPhaseCount = 4;
const char* phase_name(Phase p);

/// Per-frame options of Backend::step (what to measure; the Control says what to do).
struct FrameRequest {
  bool speeds = true;  ///< reduce per-tissue speeds in the velocity layer
  /// Measure the largest link violation after the ChainMail stage (O(N), a download on CUDA).
  bool link_violation = false;
  /// The caller still holds the value for the positions the frame starts from: it is measured
  /// again only when the ChainMail stage had work.
  bool link_violation_known = false;
  bool frame_end_guard = true;  ///< run the frame-end fold guard (restore_frame_end)
};

/// What one frame did (Backend::step).
struct FrameStats {
  PropagateStats propagate;   ///< zero on idle frames
  RelaxStats relax;
  RestoreStats restore;       ///< the ChainMail stage's link restoration
  RestoreStats frame_end;     ///< the frame-end fold guard (zero when not run)
  SpeedStats speeds;          ///< filled when requested
  Index chainmail_active_bricks = 0;  ///< bricks with work after the ChainMail stage
  Index active_bricks = 0;    ///< bricks that had work in any stage of the frame (the union)
  Index active_elements = 0;  ///< elements in those bricks
  bool link_violation_measured = false;
  float max_link_violation = 0;  ///< when measured
  std::array<double, kPhaseCount> phase_ms{};  ///< per Phase; 0 for a phase that did not run
};

/// A state resident on a backend. A backend holds one; step() advances it in place (in == out):
/// a second state would hold every per-element array twice (docs/architecture.md, "The seam").
struct StateHandle {
  const void* backend = nullptr;
  bool operator==(const StateHandle&) const = default;
};

enum class BackendKind { Cpu, Cuda };
const char* backend_name(BackendKind k);
BackendKind parse_backend(const std::string& s, const std::string& what);

class Backend {
 public:
  virtual ~Backend() = default;
  virtual BackendKind kind() const = 0;

  // --- the seam: the pipeline (Simulation) uses these ---

  /// Uploads the model, params and a state (displacements, velocities, flags are taken from it)
  /// as the resident state; no FIXED set is installed until the next step or apply_control().
  void load(const Model& m, const Params& p, const State& s) {
    upload(m, p, s);
    applied_revision_ = 0;
    link_metrics_.reset();  // the links may be new
    link_disp_since_ = 0;
  }
  /// The one reload path: the model the backend was loaded with (same object) or the params
  /// changed (ModelChange flags). Materials or anchors: the resident state is reloaded with the
  /// new tables and every brick looked at again; params only: the derived constants change, the
  /// bricks are checked against the new boundary margin (a new brick size reloads).
  void notify_model_changed(unsigned changes, const Params& p);
  /// The state the backend holds.
  StateHandle resident() const { return StateHandle{this}; }
  /// One frame in SPEC §6 order: install `c` if its revision is new (validated first), X- <- X,
  /// propagation on deformation frames, relaxation, link restoration, (the link violation when
  /// asked), velocity layer, frame-end fold guard. `in` and `out` must both be resident().
  FrameStats step(StateHandle in, StateHandle out, const Control& c, const FrameRequest& r);
  /// Installs the FIXED set of `c` (validated first: a refused control changes nothing).
  void apply_control(const Control& c);

  virtual const Model& model() const = 0;
  virtual const Params& params() const = 0;

  // --- stage primitives: step() runs them; stage-level tests and benchmarks call them ---

  /// X- <- X. May be a no-op when the backend fuses the copy into velocity_layer().
  virtual void snapshot() = 0;
  /// Timestamped HP-ChainMail wave from the FIXED elements (SPEC §4).
  virtual PropagateStats propagate() = 0;
  /// Up to `sweeps` relaxation sweeps with early exit (SPEC §4).
  virtual RelaxStats relax(int sweeps) = 0;
  /// The last step of every ChainMail stage: every link back in its box (and every element in
  /// the boundary box) where something left it, FIXED elements untouched (docs/solver.md).
  virtual RestoreStats restore_links() = 0;
  /// The same restoration after the velocity layer, at frame end: the layer's step and the
  /// boundary clamp can leave links outside their boxes and fold cells (docs/solver.md, "No
  /// fold"). X- follows every element it moves: frame-end positions are next frame's X- (SPEC §5).
  virtual RestoreStats restore_frame_end() = 0;
  /// The independent-velocity layer (SPEC §5) + boundary clamp + frame-end snapshot.
  /// Fills `speeds` when non-null (only then are speeds reduced).
  virtual void velocity_layer(SpeedStats* speeds) = 0;

  /// Bricks that had work since the frame began, in any stage (the union; 0 when the lattice
  /// is idle), and the elements in them: what the frame cost follows.
  virtual Index active_bricks() const = 0;
  virtual Index active_elements() const = 0;

  // --- not the seam: probes and transfers ---

  /// Benchmark probe: times `reps` dense passes of the velocity layer over every element and
  /// as many device-to-device copies of the positions, in the same run. The dense passes
  /// advance the state (call it at the end of a benchmark). CPU: returns available = false.
  virtual DeviceProbe probe(int /*reps*/) { return {}; }
  /// The instruction set the backend's kernels use (CPU: "avx512", "avx2" or "sse2"; empty
  /// where that does not apply).
  virtual std::string kernels() const { return {}; }
  /// Host threads the backend simulates on (CPU: its worker threads, from OMP_NUM_THREADS or
  /// the hardware; 0 where that does not apply).
  virtual int threads() const { return 0; }

  virtual void download(State& s) = 0;
  /// Displacements from rest u = X - X0 (State::disp), linear order.
  virtual void download_displacements(std::vector<Vec3>& disp) = 0;
  /// Brings a host copy up to date: `since` is what the last call returned for this copy (0: the
  /// copy holds nothing yet). A backend that knows where it wrote copies only those regions
  /// (the CPU: the bricks written since); the default downloads everything. The result equals
  /// download() / download_displacements() bit for bit.
  virtual void download_since(State& s, std::uint64_t& since) {
    download(s);
    since = 1;
  }
  virtual void download_displacements_since(std::vector<Vec3>& disp, std::uint64_t& since) {
    download_displacements(disp);
    since = 1;
  }
  virtual Vec3 displacement(Index i) = 0;

 protected:
  virtual void upload(const Model& m, const Params& p, const State& s) = 0;
  /// Params changed, the model did not (kParamsChanged alone).
  virtual void params_changed(const Params& p) = 0;
  /// Installs a validated FIXED set (grab + anchors); every other element is released.
  virtual void install_fixed(const Control& c) = 0;
  /// The frame starts: the activity of the last one is forgotten.
  virtual void begin_frame() = 0;
  /// The clock of the named phases (CPU: steady clock; CUDA: events on the backend's stream).
  virtual void phase_begin(Phase p) = 0;
  virtual void phase_end(Phase p) = 0;
  /// Milliseconds between the begin and end of `p` in this frame.
  virtual double phase_ms(Phase p) = 0;

 private:
  std::uint64_t applied_revision_ = 0;  ///< of the installed FIXED set; 0: none installed
  IncrementalMetrics link_metrics_;     ///< FrameRequest::link_violation, measured where the frame moved
  std::vector<Vec3> link_disp_;         ///< its download, kept up to date (download_displacements_since)
  std::uint64_t link_disp_since_ = 0;
};

}  // namespace hpcm
