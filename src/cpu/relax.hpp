#pragma once
// The CPU relaxation (SPEC §4): red-black Gauss-Seidel sweeps over the bricks that changed in
// the previous sweep and their face neighbours, from the rule of solver/rules.hpp. Bricks
// skipped by that schedule would compute exactly what they computed last time (their inputs
// did not change), so the brick-sparse schedule gives the same floats as sweeping everything.
//
// One colour of one lattice row is a unit-stride run in the storage (cpu/storage.hpp). Interior
// runs go through a SIMD kernel (AVX2 when the CPU has it, SSE2 otherwise; chosen at run
// time) that performs, lane by lane, the floating-point operations of the scalar rule in the
// same order, so every path gives the same bits. Border elements, and any element whose
// neighbours' boxes do not intersect, take the scalar rule.
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "cpu/storage.hpp"
#include "cpu/worker_pool.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"
#include "solver/rules.hpp"

namespace hpcm::cpu {

/// What one relaxation pass reads and writes.
struct RelaxContext {
  const Layout* lay;
  float* p[3];                   ///< displacements from rest, storage order
  const float* weight;           ///< 1 / (tau + 1e-4) per element
  const float* link_tau[3];      ///< tolerance of each element's +x, +y, +z link
  const std::uint8_t* flags;
  const float* time;             ///< arrival times (tie-break of the general rule)
  const Model* model;            ///< tolerances for the general rule
  solver::Wall wall;             ///< lattice coordinates (per element: solver::element_wall)
  float omega;
  /// solver::squared_length_bound of SolverParams::relax_threshold and relax_slack: the kernels
  /// compare squared lengths (solver::relax_step_applies), with the outcome of the lengths.
  float threshold_sq, slack_sq;
};

/// The context of a relaxation of the storage `st` of model `m` with these solver settings.
RelaxContext make_relax_context(Storage& st, const Model& m, const solver::Wall& wall, const SolverParams& s);

/// One colour's elements with x0 <= x < x1 in rows y0 <= y < y1 of plane z (in each row, the
/// half whose elements have that colour: x = 2j + h). An element j that moves marks brick
/// column col_changed[(j - col_base) / col_width].
struct RelaxRun {
  int colour, y0, y1, z, x0, x1;
  std::uint8_t* col_changed;
  int col_base, col_width;
  bool prefetch;  ///< the first pass of a thread over this plane: prefetch what it reads first
};

/// Result of a run: largest correction applied (0: nothing moved).
using RelaxRunKernel = float (*)(const RelaxContext&, const RelaxRun&);

/// The scalar rule for the element at lattice (x, y, z): moves it when the correction is at
/// least the threshold; returns the correction applied (0 if none).
float relax_element_scalar(const RelaxContext& c, int x, int y, int z);

class Relaxation {
 public:
  void init(const solver::BrickGrid& grid, RelaxRunKernel kernel);
  /// Up to `sweeps` sweeps (cpu/relax.cpp has the schedule), starting from the bricks marked
  /// in `hot` and their face neighbours; stops early where nothing moves. Bricks whose
  /// elements moved are marked in `touched`; `hot` gets the bricks the last sweep changed;
  /// bricks it worked on are marked in `worked`.
  RelaxStats run(const RelaxContext& ctx, int sweeps, std::vector<std::uint8_t>& hot,
                 std::vector<std::uint8_t>& touched, std::vector<std::uint8_t>& worked, WorkerPool& pool);

 private:
  /// Per cell of plane z, whether phase p must process it (see the schedule in relax.cpp).
  void cells_to_process(int p, int z, std::uint8_t* active) const;
  /// One phase over plane z; `prefetch`: the first pass over that plane this frame.
  float phase(const RelaxContext& ctx, int p, int z, bool prefetch, Index& active_cells);
  /// Whether phase p may process plane z now (its inputs are final).
  bool plane_ready(int p, int z) const;
  /// One thread's share of a run() with P phases: takes ready planes until all are done.
  void work_until_done(const RelaxContext& ctx, int P);
  std::uint8_t* worked_ = nullptr;  ///< per brick, during run()
  solver::BrickGrid grid_;
  RelaxRunKernel kernel_ = nullptr;
  Index cells_ = 0;                     ///< brick columns per plane
  std::vector<std::uint8_t> start_;     ///< per brick: work of the first sweep
  std::vector<std::uint8_t> changed_;   ///< [phase][plane][cell]: an element moved
  /// Per phase of a run(): planes finished (in ascending order), whether a thread is working
  /// on it, and what it found (written only by the thread holding the claim). One cache line
  /// each: the threads poll the counters.
  struct alignas(64) PhaseProgress {
    std::atomic<int> planes{0};
    std::atomic<bool> claimed{false};
    float max_correction = 0.0f;
    Index cells = 0;
  };
  std::unique_ptr<PhaseProgress[]> progress_;
  int progress_size_ = 0;
  std::atomic<std::uint32_t> planes_done_{0};  ///< bumped per plane: idle threads wait on it (futex-sized)
  std::atomic<int> sleepers_{0};               ///< threads waiting on planes_done_
};

}  // namespace hpcm::cpu
