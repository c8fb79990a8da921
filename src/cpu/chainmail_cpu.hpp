#pragma once
// The CPU backend's HP-ChainMail (SPEC §4), from the shared rules of src/solver: timestamped
// propagation processed in time buckets (label-setting, exact, OpenMP inside large buckets)
// and brick-sparse red-black Gauss-Seidel relaxation. Knows nothing about velocities: it moves positions and reports which bricks it
// touched.
//
// Why buckets and not plain Jacobi sweeps: an element's time depends on whether it moved,
// and whether it moved depends on which neighbours are earlier, so times are not monotone
// during Jacobi sweeps and the sweeps can cycle forever (seen on real CT). Every link has
// w >= delta (the smallest link penalty), so all candidate times in the bucket
// [k*delta, (k+1)*delta) come from elements already final in earlier buckets: each bucket is
// decided by a short, provably finite Jacobi iteration, and the result is exactly the
// Dijkstra-order result (docs/solver.md).
#include <vector>

#include "hpcm/state.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"
#include "solver/neighbours.hpp"
#include "solver/rules.hpp"

namespace hpcm::cpu {

using solver::BrickGrid;
using solver::Neighbour;

class ChainMailCpu {
 public:
  void init(const Model& m, int brick_size);
  /// The boundary box every clamp respects (solver::Wall).
  void set_wall(const solver::Wall& w) { wall_ = w; }
  const solver::Wall& wall() const { return wall_; }

  /// Wave from the FIXED elements (`fixed`, positions already at their targets in `pos`).
  /// Non-FIXED elements start from `pre` (X-). Writes pos and time.
  PropagateStats propagate(const Model& m, std::vector<Vec3>& pos, const std::vector<Vec3>& pre,
                           std::vector<float>& time, const std::vector<std::uint8_t>& flags,
                           const std::vector<Index>& fixed, int max_sweeps);

  /// Up to `sweeps` red-black sweeps over hot bricks and their neighbours; corrections
  /// smaller than `threshold` are skipped; early exit when no correction remains.
  RelaxStats relax(const Model& m, std::vector<Vec3>& pos, const std::vector<float>& time,
                   const std::vector<std::uint8_t>& flags, int sweeps, float threshold, float omega);

  const BrickGrid& grid() const { return grid_; }
  /// Bricks whose positions changed this frame (propagation or relaxation).
  std::vector<std::uint8_t>& touched() { return touched_; }
  /// Bricks that relaxation must look at next (changed recently).
  std::vector<std::uint8_t>& hot() { return hot_; }
  /// Bricks processed by the last propagate/relax calls (for reporting).
  Index last_active_bricks() const { return last_active_; }

  /// Gathers the neighbours of element (x, y, z) into nb; returns their count.
  static int gather(const Model& m, const Vec3* pos, const float* time, int x, int y, int z, Index i, Neighbour* nb);

 private:
  BrickGrid grid_;
  solver::Wall wall_;
  std::vector<std::uint8_t> touched_, hot_, changed_;
  std::vector<float> weight_;                ///< relaxation weight 1/(tau + 1e-4) per element
  std::vector<Index> list_;
  // propagation
  float delta_ = 0;                          ///< bucket width: smallest link w of the model
  std::vector<std::uint8_t> final_;          ///< element decided in this wave
  std::vector<Index> reached_;               ///< elements whose time was set in the last wave
  std::vector<std::vector<Index>> buckets_;  ///< pending elements per time bucket
  std::vector<float> scratch_t_;
  std::vector<Vec3> scratch_p_;
  Index last_active_ = 0;
};

}  // namespace hpcm::cpu
