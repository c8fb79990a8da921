#include "cpu/velocity_layer_cpu.hpp"

#include <algorithm>

#include "hpcm/state.hpp"

namespace hpcm::cpu {

using dynamics::LayerConstants;
using dynamics::velocity_update;

void VelocityLayerCpu::apply(const Model& m, const LayerConstants& k, const BrickGrid& grid, LayerBuffers buf,
                             std::vector<std::uint8_t>& touched, std::vector<std::uint8_t>& hot, std::vector<std::uint8_t>& moved,
                             SpeedStats* speeds) {
  list_.clear();
  for (Index b = 0; b < grid.count; ++b)
    if (touched[b] || has_velocity_[b]) list_.push_back(b);
  last_bricks_ = static_cast<Index>(list_.size());
  if (speeds) partial_.assign(list_.size(), SpeedStats{});
  Vec3* pos = buf.pos->data();
  Vec3* pre = buf.pre->data();
  Vec3* vel = buf.vel->data();
  const std::uint8_t* flags = buf.flags->data();
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t j = 0; j < list_.size(); ++j) {
    const Index b = list_[j];
    Int3 lo, hi;
    grid.range(b, lo, hi);
    bool any_velocity = false, moved_by_velocity = false;
    SpeedStats local;
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
          const Index i = m.index(x, y, z);
          const int t = m.tissue[i];
          const Vec3 post = pos[i], before = pre[i];
          Vec3 v = vel[i];
          const Vec3 out = velocity_update(k, t, (flags[i] & kFixed) != 0, before, post,
                                           Vec3{float(x), float(y), float(z)}, v);
          vel[i] = v;
          pos[i] = out;
          pre[i] = out;  // frame-end snapshot: next frame's X-
          if (!(v == Vec3{})) any_velocity = true;
          if (!(out == post)) moved_by_velocity = true;
          if (speeds) {
            const float sp = norm(out - before);
            local.sum[t] += sp;
            local.max[t] = std::max(local.max[t], sp);
            if (sp > 0) ++local.moved;
          }
        }
    has_velocity_[b] = any_velocity;
    if (moved_by_velocity) hot[b] = moved[b] = 1;
    touched[b] = 0;
    if (speeds) partial_[j] = local;
  }
  if (speeds) {
    // Sequential, fixed-order sum of per-brick partials: reproducible across thread counts.
    std::array<double, kTissueCount> sum{};
    SpeedStats total;
    for (const SpeedStats& s : partial_) {
      for (int t = 0; t < kTissueCount; ++t) {
        sum[t] += s.sum[t];
        total.max[t] = std::max(total.max[t], s.max[t]);
      }
      total.moved += s.moved;
    }
    for (int t = 0; t < kTissueCount; ++t) total.sum[t] = static_cast<float>(sum[t]);
    *speeds = total;
  }
}

}  // namespace hpcm::cpu
