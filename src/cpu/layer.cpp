#include "cpu/layer.hpp"

#include <algorithm>
#include <array>

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
  pool.run(static_cast<std::int64_t>(runs_.size()), [&](std::int64_t item) {
    const BrickRun& br = runs_[static_cast<std::size_t>(item)];
    const Index row = static_cast<Index>(nb.x) * (br.by + static_cast<Index>(nb.y) * br.bz);
    std::uint8_t* col_velocity = has_velocity_.data() + row + br.bx0;
    std::uint8_t* col_moved = moved_now_.data() + row + br.bx0;
    std::fill(col_velocity, col_velocity + (br.bx1 - br.bx0), 0);
    float* col_speed = speed_.data() + row + br.bx0;
    std::fill(col_speed, col_speed + (br.bx1 - br.bx0), 0.0f);
    const std::uint8_t* col_asleep = asleep_.data() + row + br.bx0;
    const int x0 = br.bx0 * B, x1 = std::min(br.bx1 * B, L.dims.x);
    const int y1 = std::min((br.by + 1) * B, L.dims.y), z1 = std::min((br.bz + 1) * B, L.dims.z);
    SpeedStats* local = speeds ? &partial_[static_cast<std::size_t>(item)] : nullptr;
    for (int z = br.bz * B; z < z1; ++z)
      for (int y = br.by * B; y < y1; ++y)
        for (int h = 0; h < 2; ++h)  // elements x = 2j + h in [x0, x1), x0 even
          kernel_(st, k, LayerRow{h, y, z, x0 / 2, (x1 - h + 1) / 2, col_asleep, col_velocity, col_moved, col_speed, x0 / 2, B / 2},
                  local);
    for (int bx = br.bx0; bx < br.bx1; ++bx) touched[row + bx] = 0;
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
