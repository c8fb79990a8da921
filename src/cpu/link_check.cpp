#include "cpu/link_check.hpp"

#include <algorithm>
#include <cstring>

#include "core/link_box.hpp"
#include "cpu/layer_tasks.hpp"
#include "solver/restore.hpp"

namespace hpcm::cpu {

void LinkCheck::run(const Storage& st, const solver::BrickGrid& grid, const std::vector<Index>& bricks,
                    const solver::Wall& wall, std::vector<Index>& seeds, RestoreStats& stats, WorkerPool& pool) {
  const Layout& L = st.lay;
  const int d[3] = {L.dims.x, L.dims.y, L.dims.z};
  const Index step[3] = {1, d[0], static_cast<Index>(d[0]) * d[1]};
  // Bricks listed in ascending order; consecutive ones in the same brick row form a span.
  spans_.clear();
  for (std::size_t i = 0; i < bricks.size(); ++i) {
    const Index b = bricks[i];
    if (!spans_.empty()) {
      Span& last = spans_.back();
      const Index next = last.first_brick + last.count;
      if (b == next && b % grid.nb.x != 0) {
        ++last.count;
        continue;
      }
    }
    spans_.push_back({b, 1, {}, {}});
  }
  for (Span& span : spans_) {
    Int3 lo_last, hi_last;
    grid.range(span.first_brick, span.lo, span.hi);
    grid.range(span.first_brick + span.count - 1, lo_last, hi_last);
    span.hi.x = hi_last.x;
  }
  // Tasks by layer of bricks (tasks_by_layer). The results do not depend on the tasks: seeds
  // are sorted below, and the statistics are counts and a maximum.
  const Index layer_bricks = static_cast<Index>(grid.nb.x) * grid.nb.y;
  tasks_by_layer(spans_.size(), [&](std::size_t i) { return spans_[i].first_brick / layer_bricks; }, min_layer_tasks(pool.threads()),
                 tasks_);
  const std::size_t items = tasks_.size() - 1;
  if (found_.size() < items) found_.resize(items);
  if (flagged_.size() < items) flagged_.resize(items);
  partial_.assign(items, RestoreStats{});
  pool.run(static_cast<std::int64_t>(items), [&](std::int64_t item) {
    std::vector<Index>& out = found_[static_cast<std::size_t>(item)];
    std::vector<int>& flagged = flagged_[static_cast<std::size_t>(item)];
    RestoreStats& ps = partial_[static_cast<std::size_t>(item)];
    out.clear();
    // The exact check of one element (what solver::find_violations does).
    auto check_element = [&](int x, int y, int z) {
      const Index k = L.at(x, y, z);
      const Vec3 pe{st.p[0][k], st.p[1][k], st.p[2][k]};
      const Index e = x + static_cast<Index>(d[0]) * (y + static_cast<Index>(d[1]) * z);
      const int c[3] = {x, y, z};
      bool seed_e = false;
      for (int a = 0; a < 3; ++a) {
        const float outside = std::max(solver::wall_lo_of(wall, a, c[a]) - pe[a], pe[a] - solver::wall_hi_of(wall, a, c[a]));
        if (outside > solver::kRestoreTolerance) {
          ++ps.violated_links;
          ps.max_violation = std::max(ps.max_violation, outside);
          seed_e = true;
        }
        if (c[a] + 1 >= d[a]) continue;
        const Index kn = L.at(x + (a == 0), y + (a == 1), z + (a == 2));
        const float v = link_violation(pe, Vec3{st.p[0][kn], st.p[1][kn], st.p[2][kn]}, st.link(a, k), a);
        if (v > solver::kRestoreTolerance) {
          ++ps.violated_links;
          ps.max_violation = std::max(ps.max_violation, v);
          seed_e = true;
          out.push_back(e + step[a]);
        }
      }
      if (seed_e) out.push_back(e);
    };
    const std::size_t first_span = tasks_[static_cast<std::size_t>(item)], end_span = tasks_[static_cast<std::size_t>(item) + 1];
    for (int z = spans_[first_span].lo.z; z < spans_[first_span].hi.z; ++z)  // the task's layer
      for (std::size_t i = first_span; i < end_span; ++i) {
        const Int3 lo = spans_[i].lo, hi = spans_[i].hi;
        for (int y = lo.y; y < hi.y; ++y)
          for (int h = 0; h < 2; ++h) {
            // Elements x = 2j + h in [lo.x, hi.x); the vector filter covers those whose +x
            // neighbour exists (x + 1 < nx), the rest (the row's last element) are checked exactly.
            const int j0 = lo.x / 2;  // lo.x is even
            const int j1 = (hi.x - h + 1) / 2;
            const int jx = std::min(j1, (d[0] - h) / 2);  // 2j + h + 1 < nx; jx >= j0 as lo.x < nx
            flagged.clear();
            filter_(st, wall, h, y, z, j0, jx, flagged);
            for (int f : flagged) check_element(2 * f + h, y, z);
            for (int j = jx; j < j1; ++j) check_element(2 * j + h, y, z);
          }
      }
  });
  const std::size_t first = seeds.size();
  for (std::size_t item = 0; item < items; ++item) {
    seeds.insert(seeds.end(), found_[item].begin(), found_[item].end());
    stats.violated_links += partial_[item].violated_links;
    stats.max_violation = std::max(stats.max_violation, partial_[item].max_violation);
  }
  std::sort(seeds.begin() + static_cast<std::ptrdiff_t>(first), seeds.end());
  seeds.erase(std::unique(seeds.begin() + static_cast<std::ptrdiff_t>(first), seeds.end()), seeds.end());
}

}  // namespace hpcm::cpu
