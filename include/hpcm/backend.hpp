#pragma once
// The backend seam: the primitive stages of one frame, implemented once on the CPU (src/cpu)
// and once in CUDA (src/cuda) from the shared rules of src/solver and src/dynamics. The frame
// pipeline (simulation.hpp) is written once and calls these in SPEC §6 order for every
// backend; backend_factory.hpp creates them.
#include <array>
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

enum class BackendKind { Cpu, Cuda };
const char* backend_name(BackendKind k);
BackendKind parse_backend(const std::string& s, const std::string& what);

class Backend {
 public:
  virtual ~Backend() = default;
  virtual BackendKind kind() const = 0;

  /// Uploads the model, params and a state (displacements, velocities, flags are taken from it).
  virtual void load(const Model& m, const Params& p, const State& s) = 0;
  /// Parameter change that keeps the model (dynamics, relaxation settings).
  virtual void set_params(const Params& p) = 0;
  /// The FIXED set for this frame (grab + anchors) with targets (displacements from rest); all
  /// others are released.
  virtual void set_fixed(const std::vector<Index>& elements, const std::vector<Vec3>& targets,
                         const std::vector<std::uint8_t>& flags) = 0;

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

  /// Bricks that had work this frame (any stage; 0 when the lattice is idle) and the elements
  /// in them: what the frame cost follows.
  virtual Index active_bricks() const = 0;
  virtual Index active_elements() const = 0;
  /// Stage timer: mark(k) at stage boundaries, elapsed_ms(a, b) between two marks of the
  /// current frame (CPU: steady clock; CUDA: events).
  virtual void mark(int slot) = 0;
  virtual double elapsed_ms(int from_slot, int to_slot) = 0;

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
  virtual Vec3 displacement(Index i) = 0;
};

}  // namespace hpcm
