#include "cpu/layer.hpp"

#include <algorithm>
#include <array>

#include "cpu/layer_tasks.hpp"

namespace hpcm::cpu {

Index VelocityLayer::bricks_with_velocity() const {
  return static_cast<Index>(std::count(has_velocity_.begin(), has_velocity_.end(), 1));
}

void VelocityLayer::apply(Storage& st, const dynamics::LayerConstants& k, float sleep_speed, bool all,
                          std::vector<std::uint8_t>& touched,
                          std::vector<std::uint8_t>& hot, std::vector<std::uint8_t>& moved,
                          std::vector<std::uint8_t>& worked, SpeedStats* speeds, WorkerPool& pool) {
  // Work: bricks touched this frame or carrying velocity, merged along x into runs so that the
  // SIMD kernel sees rows longer than one brick.
  runs_.clear();
  last_bricks_ = 0;
  const Int3 nb = grid_.nb;
  for (int bz = 0; bz < nb.z; ++bz)
    for (int by = 0; by < nb.y; ++by) {
      const Index row = static_cast<Index>(nb.x) * (by + static_cast<Index>(nb.y) * bz);
      auto on = [&](int bx) { return all || touched[row + bx] || has_velocity_[row + bx]; };
      for (int bx = 0; bx < nb.x;) {
        if (!on(bx)) {
          ++bx;
          continue;
        }
        int end = bx + 1;
        while (end < nb.x && on(end)) ++end;
        runs_.push_back({by, bz, bx, end});
        last_bricks_ += end - bx;
        for (int c = bx; c < end; ++c) worked[static_cast<std::size_t>(row + c)] = 1;
        bx = end;
      }
    }
  for (Index b = 0; b < grid_.count; ++b)
    asleep_[static_cast<std::size_t>(b)] = sleep_speed > 0.0f && !touched[b] && speed_[static_cast<std::size_t>(b)] < sleep_speed;
  if (speeds) partial_.assign(runs_.size(), SpeedStats{});
  moved_now_.assign(static_cast<std::size_t>(grid_.count), 0);
  const int B = grid_.size;
  const Layout& L = st.lay;
  // Tasks by layer of bricks (tasks_by_layer). The additions into each run's speed partial keep
  // their order (z, y, h) whatever the tasks, and tasks share no brick column.
  tasks_by_layer(runs_.size(), [&](std::size_t i) { return runs_[i].bz; }, min_layer_tasks(pool.threads()), tasks_);
  pool.run(static_cast<std::int64_t>(tasks_.size()) - 1, [&](std::int64_t item) {
    const std::size_t first = tasks_[static_cast<std::size_t>(item)], last = tasks_[static_cast<std::size_t>(item) + 1];
    auto first_brick = [&](const BrickRun& br) { return static_cast<Index>(nb.x) * (br.by + static_cast<Index>(nb.y) * br.bz) + br.bx0; };
    for (std::size_t i = first; i < last; ++i) {
      const BrickRun& br = runs_[i];
      const Index c0 = first_brick(br);
      std::fill(has_velocity_.data() + c0, has_velocity_.data() + c0 + (br.bx1 - br.bx0), 0);
      std::fill(speed_.data() + c0, speed_.data() + c0 + (br.bx1 - br.bx0), 0.0f);
      std::fill(touched.begin() + c0, touched.begin() + c0 + (br.bx1 - br.bx0), 0);  // read above, before the pass
    }
    const int bz = runs_[first].bz;
    const int z1 = std::min((bz + 1) * B, L.dims.z);
    for (int z = bz * B; z < z1; ++z)
      for (std::size_t i = first; i < last; ++i) {
        const BrickRun& br = runs_[i];
        const Index c0 = first_brick(br);
        const int x0 = br.bx0 * B, x1 = std::min(br.bx1 * B, L.dims.x);
        const int y1 = std::min((br.by + 1) * B, L.dims.y);
        SpeedStats* local = speeds ? &partial_[i] : nullptr;
        for (int y = br.by * B; y < y1; ++y)
          for (int h = 0; h < 2; ++h)  // elements x = 2j + h in [x0, x1), x0 even
            kernel_(st, k, LayerRow{h, y, z, x0 / 2, (x1 - h + 1) / 2, asleep_.data() + c0, has_velocity_.data() + c0,
                                    moved_now_.data() + c0, speed_.data() + c0, x0 / 2, B / 2},
                    local);
      }
  });
  for (std::size_t b = 0; b < moved_now_.size(); ++b)
    if (moved_now_[b]) hot[b] = moved[b] = 1;
  if (speeds) {
    // Sequential, fixed-order sum of per-run partials: reproducible across thread counts.
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
