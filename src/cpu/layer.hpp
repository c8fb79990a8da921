#pragma once
// The CPU loop of the velocity layer (the per-element rule is dynamics/velocity_update.hpp),
// brick-sparse: only bricks that ChainMail touched this frame or that still carry velocity are
// visited; a brick neither touched nor carrying velocity has dX = 0 and V = 0 everywhere, so the
// rule would leave it exactly as it is.
#include <cstdint>
#include <vector>

#include "cpu/kernels.hpp"
#include "cpu/storage.hpp"
#include "cpu/worker_pool.hpp"
#include "dynamics/velocity_update.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"

namespace hpcm::cpu {

class VelocityLayer {
 public:
  void init(const solver::BrickGrid& grid, LayerRowKernel kernel) {
    grid_ = grid;
    kernel_ = kernel;
    has_velocity_.assign(static_cast<std::size_t>(grid.count), 0);
    speed_.assign(static_cast<std::size_t>(grid.count), 0.0f);
    asleep_.assign(static_cast<std::size_t>(grid.count), 0);
  }
  /// Runs the layer over touched bricks and bricks with velocity (every brick when `all`),
  /// writes X_{t+1} into p and q (the frame-end snapshot), marks bricks it moved in `hot` and
  /// `moved` and bricks it visited in `worked`, and clears `touched`. Fills `speeds` when
  /// non-null. A brick that ChainMail left untouched this frame and whose velocities all stayed
  /// below `sleep_speed` last frame comes to rest (its velocities become 0; 0 = never).
  void apply(Storage& st, const dynamics::LayerConstants& k, float sleep_speed, bool all, std::vector<std::uint8_t>& touched,
             std::vector<std::uint8_t>& hot, std::vector<std::uint8_t>& moved, std::vector<std::uint8_t>& worked,
             SpeedStats* speeds, WorkerPool& pool);
  Index last_bricks() const { return last_bricks_; }
  /// Bricks whose elements carry velocity (for reporting).
  Index bricks_with_velocity() const;

 private:
  solver::BrickGrid grid_;
  LayerRowKernel kernel_ = nullptr;
  std::vector<std::uint8_t> has_velocity_;
  std::vector<float> speed_;            ///< per brick: largest |V| (before the clamp) of the last visit
  std::vector<std::uint8_t> asleep_;    ///< per brick: no dynamics this frame
  struct BrickRun {
    int by, bz, bx0, bx1;  ///< bricks [bx0, bx1) of brick row (by, bz)
  };
  std::vector<BrickRun> runs_;
  std::vector<std::size_t> tasks_;  ///< runs_ index where each task starts, and the end (tasks_by_layer)
  std::vector<std::uint8_t> moved_now_;
  std::vector<SpeedStats> partial_;
  Index last_bricks_ = 0;
};

}  // namespace hpcm::cpu
