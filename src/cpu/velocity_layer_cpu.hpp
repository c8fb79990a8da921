#pragma once
// The CPU backend's loop of the velocity layer (the per-element rule is
// dynamics/velocity_update.hpp), brick-sparse: only bricks that ChainMail touched this frame or
// that still carry velocity are visited; everything else costs nothing.
#include <vector>

#include "dynamics/velocity_update.hpp"
#include "hpcm/model.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"

namespace hpcm::cpu {

using solver::BrickGrid;

struct LayerBuffers {
  std::vector<Vec3>* pos;                    ///< in: X+ ; out: X_{t+1}
  std::vector<Vec3>* pre;                    ///< in: X- ; out: X_{t+1} (frame-end snapshot, fused)
  std::vector<Vec3>* vel;
  const std::vector<std::uint8_t>* flags;
};

class VelocityLayerCpu {
 public:
  void init(const BrickGrid& grid) { has_velocity_.assign(static_cast<std::size_t>(grid.count), 0); }
  /// Runs the layer over touched bricks and bricks with velocity; marks bricks the layer moved
  /// in `hot` (relaxation must revisit them) and in `moved`, and clears `touched`.
  void apply(const Model& m, const dynamics::LayerConstants& k, const BrickGrid& grid, LayerBuffers buf,
             std::vector<std::uint8_t>& touched, std::vector<std::uint8_t>& hot, std::vector<std::uint8_t>& moved,
             SpeedStats* speeds);
  Index last_bricks() const { return last_bricks_; }
  void clear() { std::fill(has_velocity_.begin(), has_velocity_.end(), 0); }

 private:
  std::vector<std::uint8_t> has_velocity_;
  std::vector<Index> list_;
  std::vector<SpeedStats> partial_;
  Index last_bricks_ = 0;
};

}  // namespace hpcm::cpu
