#include "dynamics/velocity_update.hpp"

namespace hpcm::dynamics {

LayerConstants make_constants(const DynamicsParams& p, Int3 dims) {
  LayerConstants k{};
  k.mode = p.mode == DampingMode::None ? 0 : (p.mode == DampingMode::Simple ? 1 : 2);
  k.alpha = p.alpha;
  k.b0 = p.b0;
  k.dead_zone = p.dead_zone;
  k.v_max = p.v_max;
  k.beta = p.beta;
  const PerTissue s = p.response_scale();
  for (int t = 0; t < kTissueCount; ++t) {
    k.s[t] = s[t];
    k.b1[t] = p.b1[t];
    k.rho[t] = p.rho[t];
    k.inv_mass[t] = p.inverse_mass[t];
  }
  const int d[3] = {dims.x, dims.y, dims.z};
  for (int a = 0; a < 3; ++a) {
    k.lo[a] = -p.margin;
    k.hi[a] = static_cast<float>(d[a] - 1) + p.margin;
  }
  return k;
}

}  // namespace hpcm::dynamics
