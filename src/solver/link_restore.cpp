#include "solver/link_restore.hpp"

#include <algorithm>

#include "hpcm/state.hpp"
#include "solver/neighbours.hpp"

namespace hpcm::solver {

void find_violations(const Model& m, const BrickGrid& grid, const std::vector<Index>& bricks, const RestoreAccess& pos,
                     const Wall& wall, std::vector<Index>& seeds, RestoreStats& st) {
  const Index sx[3] = {1, m.dims.x, static_cast<Index>(m.dims.x) * m.dims.y};
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  const std::size_t first = seeds.size();
  for (Index bk : bricks) {
    Int3 lo, hi;
    grid.range(bk, lo, hi);
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
          const Index e = m.index(x, y, z);
          const Vec3 pe = pos.position(e);
          const int c[3] = {x, y, z};
          bool seed_e = false;
          for (int a = 0; a < 3; ++a) {
            const float outside = std::max(wall.lo[a] - pe[a], pe[a] - wall.hi[a]);
            if (outside > kRestoreTolerance) {
              ++st.violated_links;
              st.max_violation = std::max(st.max_violation, outside);
              seed_e = true;
            }
            if (c[a] + 1 >= d[a]) continue;
            const Index n = e + sx[a];
            const float v = link_violation(pe, pos.position(n), m.link(a, e), a);
            if (v > kRestoreTolerance) {
              ++st.violated_links;
              st.max_violation = std::max(st.max_violation, v);
              seed_e = true;
              seeds.push_back(n);
            }
          }
          if (seed_e) seeds.push_back(e);
        }
  }
  std::sort(seeds.begin() + static_cast<std::ptrdiff_t>(first), seeds.end());
  seeds.erase(std::unique(seeds.begin() + static_cast<std::ptrdiff_t>(first), seeds.end()), seeds.end());
}

void LinkRestorer::init(const Model& m) {
  const std::size_t n = static_cast<std::size_t>(m.size());
  queued_.assign(n, 0);
  mark_.assign(n, 0);
  moved_flag_.assign(n, 0);
  stamp_.assign(n, 0);
  epoch_ = 0;
  for (auto& v : val_) v.assign(n, 0.0f);
}

void LinkRestorer::pass(const Model& m, const RestoreAccess& pos, int b, int k, float wall_lo, float wall_hi,
                        bool upper, const std::vector<Index>& seeds) {
  const bool inward = rounds_inward(std::max(-wall_lo, wall_hi));
  queue_.clear();
  for (Index e : seeds)
    if (!queued_[e] && !pos.fixed(e)) {
      queued_[e] = 1;
      queue_.push_back(e);
    }
  // FIFO work list: an element whose value changes re-queues its neighbours. The pass is a
  // monotone fixed-point iteration, so the visiting order does not change the result.
  for (std::size_t head = 0; head < queue_.size(); ++head) {
    const Index e = queue_[head];
    queued_[e] = 0;
    const Int3 c = m.coords(e);
    float bound = upper ? wall_hi : wall_lo;
    const float xe = value(pos, b, k, e);
    const bool e_moved = mark_[e] != 0;  // changed by a pass on this axis (either copy)
    for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int a, int side, const LinkLimits& L) {
      const float cn = value(pos, b, k, n);
      if (left_as_placed(e_moved, mark_[n] != 0, xe, cn, L, a, side, b, inward)) return;
      const float lb = link_bound(cn, L, a, side, b, upper, inward);
      bound = upper ? (lb < bound ? lb : bound) : (lb > bound ? lb : bound);
    });
    float& x = value(pos, b, k, e);
    const float nx = restore_step(x, bound, upper);
    if (nx == x) continue;
    x = nx;
    if (!mark_[e]) {
      mark_[e] = 1;
      changed_.push_back(e);
    }
    for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int, int, const LinkLimits&) {
      if (!queued_[n] && !pos.fixed(n)) {
        queued_[n] = 1;
        queue_.push_back(n);
      }
    });
  }
}

void LinkRestorer::restore(const Model& m, const BrickGrid& grid, const std::vector<Index>& seeds, RestoreAccess& pos,
                           const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st) {
  if (seeds.empty()) return;
  for (int b = 0; b < 3; ++b) {
    ++epoch_;
    if (epoch_ == 0) {  // wrapped: forget every stamp
      std::fill(stamp_.begin(), stamp_.end(), 0);
      epoch_ = 1;
    }
    changed_.clear();
    // Copy 0: raise(lower(x)); copy 1: lower(raise(x)). The second pass of each copy starts
    // from the seeds and every element the first passes moved (only there can it find work).
    pass(m, pos, b, 0, wall.lo[b], wall.hi[b], true, seeds);
    pass(m, pos, b, 1, wall.lo[b], wall.hi[b], false, seeds);
    pass_seeds_ = seeds;
    pass_seeds_.insert(pass_seeds_.end(), changed_.begin(), changed_.end());
    pass(m, pos, b, 0, wall.lo[b], wall.hi[b], false, pass_seeds_);
    pass(m, pos, b, 1, wall.lo[b], wall.hi[b], true, pass_seeds_);
    // The midpoints, then lower and raise once more from them (copy 0): rounding a midpoint can
    // leave a link a float step or so outside its box; these passes move such elements by about
    // that much and put every link they touch back (exactly inside its box where the axis
    // rounds inward, restore.hpp).
    // Seeded with every changed element and its neighbours (either end of a link may have to
    // move); a seed listed twice is queued once.
    auto changed_and_neighbours = [&] {
      pass_seeds_ = changed_;
      for (Index e : changed_) {
        const Int3 c = m.coords(e);
        for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int, int, const LinkLimits&) { pass_seeds_.push_back(n); });
      }
    };
    for (Index e : changed_) val_[0][e] = val_[1][e] = 0.5f * (val_[0][e] + val_[1][e]);
    changed_and_neighbours();
    pass(m, pos, b, 0, wall.lo[b], wall.hi[b], true, pass_seeds_);
    changed_and_neighbours();
    pass(m, pos, b, 0, wall.lo[b], wall.hi[b], false, pass_seeds_);
    for (Index e : changed_) {
      mark_[e] = 0;
      const float restored = val_[0][e];
      if (restored == pos.position(e)[b]) continue;
      pos.set_coordinate(e, b, restored);
      moved[grid.brick_of_index(e)] = 1;
      if (!moved_flag_[e]) {
        moved_flag_[e] = 1;
        moved_list_.push_back(e);
      }
    }
  }
  st.moved += static_cast<Index>(moved_list_.size());
  for (Index e : moved_list_) moved_flag_[e] = 0;
  moved_list_.clear();
}

}  // namespace hpcm::solver
