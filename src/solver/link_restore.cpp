#include "solver/link_restore.hpp"

#include <algorithm>
#include <utility>

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
          const Vec3 pe = pos.displacement(e);
          const int c[3] = {x, y, z};
          bool seed_e = false;
          for (int a = 0; a < 3; ++a) {
            const float outside = std::max(wall_lo_of(wall, a, c[a]) - pe[a], pe[a] - wall_hi_of(wall, a, c[a]));
            if (outside > kRestoreTolerance) {
              ++st.violated_links;
              st.max_violation = std::max(st.max_violation, outside);
              seed_e = true;
            }
            if (c[a] + 1 >= d[a]) continue;
            const Index n = e + sx[a];
            const float v = link_violation(pe, pos.displacement(n), m.link(a, e), a);
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

namespace {

/// Sorts and deduplicates v from `first` on.
void sort_unique_from(std::vector<Index>& v, std::size_t first) {
  std::sort(v.begin() + static_cast<std::ptrdiff_t>(first), v.end());
  v.erase(std::unique(v.begin() + static_cast<std::ptrdiff_t>(first), v.end()), v.end());
}

/// The ends of the fold-violating links of elements [begin, end), appended unsorted.
void append_fold_suspects(const Model& m, const Index* begin, const Index* end, const RestoreAccess& pos,
                          std::vector<Index>& suspects) {
  for (const Index* it = begin; it != end; ++it) {
    const Index e = *it;
    const Int3 c = m.coords(e);
    const Vec3 ue = pos.displacement(e);
    for_each_face_neighbour(m.dims.x, m.dims.y, m.dims.z, c.x, c.y, c.z, e,
                            [&](Index n, int a, int, Index lo, Index hi) {
                              const Vec3 un = pos.displacement(n);
                              const Vec3& u_lo = lo == e ? ue : un;
                              const Vec3& u_hi = hi == e ? ue : un;
                              if (may_fold(u_lo, u_hi, a)) {
                                suspects.push_back(e);
                                suspects.push_back(n);
                              }
                            });
  }
}

/// The base (lowest corner) of every cell with a corner among elements [begin, end), appended
/// unsorted: up to one cell below each element on every axis.
void append_cell_bases(const Model& m, const Index* begin, const Index* end, std::vector<Index>& bases) {
  for (const Index* it = begin; it != end; ++it) {
    const Int3 c = m.coords(*it);
    for (int z = std::max(c.z - 1, 0); z <= std::min(c.z, m.dims.z - 2); ++z)
      for (int y = std::max(c.y - 1, 0); y <= std::min(c.y, m.dims.y - 2); ++y)
        for (int x = std::max(c.x - 1, 0); x <= std::min(c.x, m.dims.x - 2); ++x) bases.push_back(m.index(x, y, z));
  }
}

/// Tests the cells with bases [begin, end) (each once); appends the 8 corners of each folded
/// cell, unsorted, and returns how many folded.
Index test_cells(const Model& m, const Index* begin, const Index* end, const RestoreAccess& pos,
                 std::vector<Index>& corners) {
  const Index sy = m.dims.x, sz = static_cast<Index>(m.dims.x) * m.dims.y;
  Index folded = 0;
  for (const Index* it = begin; it != end; ++it) {
    const Index base = *it;
    // The cell's 8 corners, loaded once: every edge of a corner's test runs to another corner.
    Vec3 u[2][2][2];
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) u[k][j][i] = pos.displacement(base + i + j * sy + k * sz);
    bool fold = false;
    for (int k = 0; k < 2 && !fold; ++k)
      for (int j = 0; j < 2 && !fold; ++j)
        for (int i = 0; i < 2 && !fold; ++i) {
          const Vec3& c = u[k][j][i];
          const Vec3 dx = i ? c - u[k][j][0] : u[k][j][1] - c;
          const Vec3 dy = j ? c - u[k][0][i] : u[k][1][i] - c;
          const Vec3 dz = k ? c - u[0][j][i] : u[1][j][i] - c;
          fold = corner_determinant(dx, dy, dz) <= 0.0;
        }
    if (!fold) continue;
    ++folded;
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) corners.push_back(base + i + j * sy + k * sz);
  }
  return folded;
}

/// Splits [0, n) into chunks of at least kMinChunk elements for `parallel`.
constexpr std::int64_t kMinChunk = 256, kMaxChunks = 16;
std::int64_t chunks_for(std::size_t n) {
  return std::max<std::int64_t>(1, std::min<std::int64_t>(kMaxChunks, static_cast<std::int64_t>(n) / kMinChunk));
}
std::pair<std::size_t, std::size_t> chunk_range(std::size_t n, std::int64_t chunks, std::int64_t i) {
  return {n * static_cast<std::size_t>(i) / static_cast<std::size_t>(chunks),
          n * static_cast<std::size_t>(i + 1) / static_cast<std::size_t>(chunks)};
}

/// Runs append(begin, end, out) over chunks of `in` on `parallel`, each into its own list, and
/// appends the lists to `out` in chunk order (the callers sort them).
template <class Append>
void append_in_chunks(const std::vector<Index>& in, const ParallelFor& parallel, Append append, std::vector<Index>& out) {
  const std::int64_t chunks = chunks_for(in.size());
  std::vector<std::vector<Index>> part(static_cast<std::size_t>(chunks));
  parallel(chunks, [&](std::int64_t i) {
    const auto [b, e] = chunk_range(in.size(), chunks, i);
    append(in.data() + b, in.data() + e, part[static_cast<std::size_t>(i)]);
  });
  for (const auto& p : part) out.insert(out.end(), p.begin(), p.end());
}

}  // namespace

void find_fold_suspects(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& suspects) {
  const std::size_t first = suspects.size();
  append_fold_suspects(m, elements.data(), elements.data() + elements.size(), pos, suspects);
  sort_unique_from(suspects, first);
}

void find_fold_suspects(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& suspects, const ParallelFor& parallel) {
  const std::size_t first = suspects.size();
  append_in_chunks(
      elements, parallel,
      [&](const Index* b, const Index* e, std::vector<Index>& out) { append_fold_suspects(m, b, e, pos, out); }, suspects);
  sort_unique_from(suspects, first);
}

Index find_folded_cells(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& corners) {
  const std::size_t first = corners.size();
  std::vector<Index> bases;
  append_cell_bases(m, elements.data(), elements.data() + elements.size(), bases);
  sort_unique_from(bases, 0);
  const Index folded = test_cells(m, bases.data(), bases.data() + bases.size(), pos, corners);
  sort_unique_from(corners, first);
  return folded;
}

Index find_folded_cells(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& corners, const ParallelFor& parallel) {
  std::vector<Index> bases;
  append_in_chunks(
      elements, parallel, [&](const Index* b, const Index* e, std::vector<Index>& out) { append_cell_bases(m, b, e, out); },
      bases);
  sort_unique_from(bases, 0);  // each cell once: tested in one chunk only
  const std::size_t first = corners.size();
  append_in_chunks(
      bases, parallel,
      [&](const Index* b, const Index* e, std::vector<Index>& out) { static_cast<void>(test_cells(m, b, e, pos, out)); },
      corners);
  const Index folded = static_cast<Index>((corners.size() - first) / 8);  // 8 corners per folded cell, before the merge
  sort_unique_from(corners, first);
  return folded;
}

void LinkRestorer::guard_folds(const Model& m, const BrickGrid& grid, const std::vector<Index>& link_seeds,
                               RestoreAccess& pos, const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st) {
  if (link_seeds.empty()) return;
  guard_moved_.clear();
  record_moved_ = &guard_moved_;  // an element moved in two rounds counts once
  for (int round = 0; round <= kFoldGuardRounds; ++round) {
    // Links that may fold can only be among the links the check found outside their boxes, or
    // at the elements the guard has moved since.
    guard_elements_ = link_seeds;
    guard_elements_.insert(guard_elements_.end(), guard_moved_.begin(), guard_moved_.end());
    suspects_.clear();
    folded_corners_.clear();
    Index folded = 0;
    if (parallel_) {
      find_fold_suspects(m, guard_elements_, pos, suspects_, parallel_);
      if (!suspects_.empty()) folded = find_folded_cells(m, suspects_, pos, folded_corners_, parallel_);
    } else {
      find_fold_suspects(m, guard_elements_, pos, suspects_);
      if (!suspects_.empty()) folded = find_folded_cells(m, suspects_, pos, folded_corners_);
    }
    if (round == 0) st.violated_links = folded;
    if (folded == 0) break;
    // The last round restores every link found outside its box: then none can fold a cell.
    restore(m, grid, round < kFoldGuardRounds ? folded_corners_ : link_seeds, false, pos, wall, moved, st);
  }
  record_moved_ = nullptr;
  std::sort(guard_moved_.begin(), guard_moved_.end());
  st.moved += static_cast<Index>(std::unique(guard_moved_.begin(), guard_moved_.end()) - guard_moved_.begin());
}

void LinkRestorer::init(const Model& m) {
  const std::size_t n = static_cast<std::size_t>(m.size());
  for (Copy& c : copy_) {
    c.val.assign(n, 0.0f);
    c.stamp.assign(n, 0);
    c.flags.assign(n, 0);
  }
  moved_flag_.assign(n, 0);
  epoch_ = 0;
}

bool LinkRestorer::pass(const Model& m, const RestoreAccess& pos, int b, int k, const Wall& wall, bool upper,
                        const std::vector<Index>& seeds) {
  Copy& cp = copy_[k];
  std::vector<Index>& queue = cp.queue;
  std::vector<std::uint8_t>& flags = cp.flags;
  queue.clear();
  for (Index e : seeds)
    if (!(flags[e] & kQueued) && !pos.fixed(e)) {
      flags[e] |= kQueued;
      queue.push_back(e);
    }
  // FIFO work list: an element whose value changes re-queues its neighbours. The pass is a
  // monotone fixed-point iteration, so the visiting order does not change the result. Capped
  // (restore.hpp, kRestoreVisitsPerElement): a pass that reaches the cap stops and says so.
  const std::size_t cap = static_cast<std::size_t>(visits_per_element_) * static_cast<std::size_t>(m.size());
  std::size_t head = 0;
  for (; head < queue.size() && head < cap; ++head) {
    const Index e = queue[head];
    flags[e] &= static_cast<std::uint8_t>(~kQueued);
    const Int3 c = m.coords(e);
    float bound = upper ? wall_hi_of(wall, b, c[b]) : wall_lo_of(wall, b, c[b]);
    for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int a, int side, const LinkLimits& L) {
      const float lb = link_bound(value(pos, b, k, n), L, a, side, b, upper);
      bound = upper ? (lb < bound ? lb : bound) : (lb > bound ? lb : bound);
    });
    float& x = value(pos, b, k, e);
    const float nx = restore_step(x, bound, upper);
    if (nx == x) continue;
    x = nx;
    if (!(flags[e] & kChanged)) {
      flags[e] |= kChanged;
      cp.changed.push_back(e);
    }
    for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int, int, const LinkLimits&) {
      if (!(flags[n] & kQueued) && !pos.fixed(n)) {
        flags[n] |= kQueued;
        queue.push_back(n);
      }
    });
  }
  const bool finished = head == queue.size();
  for (; head < queue.size(); ++head) flags[queue[head]] &= static_cast<std::uint8_t>(~kQueued);  // left over at the cap
  return finished;
}

bool LinkRestorer::both_orders(const Model& m, const RestoreAccess& pos, int b, const Wall& wall,
                               const std::vector<Index>& seeds, bool every_violation, bool parallel) {
  // Copy 0: raise(lower(x)); copy 1: lower(raise(x)). Lowering an element only loosens its
  // neighbours' lower bounds (raising, their upper ones), so after a copy's first pass its second
  // can find a link outside its box by more than the tolerance only at the elements out of their
  // boxes before it and those its first pass moved. Where the seeds are every such element, each
  // copy's second pass starts from them and its own first pass's moves, and the copies run
  // through without waiting for each other.
  // Elsewhere (the fold guard's corners) both second passes start from the seeds and every move
  // of both first passes, as they always have: what one copy's moves reach, the other repairs too.
  auto for_both = [&](auto&& order) {
    if (parallel) {
      parallel_(2, [&](std::int64_t k) { order(static_cast<int>(k)); });
    } else {
      for (int k = 0; k < 2; ++k) order(k);
    }
  };
  bool ok[2] = {true, true};
  if (every_violation) {
    for_both([&](int k) {
      Copy& cp = copy_[k];
      ok[k] = pass(m, pos, b, k, wall, k == 0, seeds);
      cp.seeds = seeds;
      cp.seeds.insert(cp.seeds.end(), cp.changed.begin(), cp.changed.end());
      ok[k] = pass(m, pos, b, k, wall, k != 0, cp.seeds) && ok[k];
    });
  } else {
    for_both([&](int k) { ok[k] = pass(m, pos, b, k, wall, k == 0, seeds); });
    pass_seeds_ = seeds;
    for (const Copy& cp : copy_) pass_seeds_.insert(pass_seeds_.end(), cp.changed.begin(), cp.changed.end());
    for_both([&](int k) { ok[k] = pass(m, pos, b, k, wall, k != 0, pass_seeds_) && ok[k]; });
  }
  return ok[0] && ok[1];
}

void LinkRestorer::restore(const Model& m, const BrickGrid& grid, const std::vector<Index>& seeds, RestoreAccess& pos,
                           const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st) {
  restore(m, grid, seeds, true, pos, wall, moved, st);
}

void LinkRestorer::restore(const Model& m, const BrickGrid& grid, const std::vector<Index>& seeds, bool every_violation,
                           RestoreAccess& pos, const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st) {
  if (seeds.empty()) return;
  // The two orders on two threads pay off only where the passes have work to share.
  constexpr std::size_t kParallelSeeds = 64;
  const bool parallel = parallel_ && seeds.size() >= kParallelSeeds;
  Copy& c0 = copy_[0];
  Copy& c1 = copy_[1];
  bool ok = true;
  for (int b = 0; b < 3; ++b) {
    if (++epoch_ == 0) {  // wrapped: forget every stamp
      for (Copy& c : copy_) std::fill(c.stamp.begin(), c.stamp.end(), 0);
      epoch_ = 1;
    }
    ok = both_orders(m, pos, b, wall, seeds, every_violation, parallel) && ok;
    // Every element either copy moved, once, in copy 0's list (its flags say which are listed).
    for (Index e : c1.changed)
      if (!(c0.flags[e] & kChanged)) {
        c0.flags[e] |= kChanged;
        c0.changed.push_back(e);
      }
    for (Index e : c1.changed) c1.flags[e] &= static_cast<std::uint8_t>(~kChanged);
    c1.changed.clear();
    // The midpoints, then lower and raise once more from them (copy 0): rounding a midpoint can
    // leave a link a float step or so outside its box; these passes move such elements by about
    // that much and put every link they touch back (within half a float step, restore.hpp).
    // Seeded with every changed element and its neighbours (either end of a link may have to
    // move); a seed listed twice is queued once.
    auto changed_and_neighbours = [&] {
      pass_seeds_ = c0.changed;
      for (Index e : c0.changed) {
        const Int3 c = m.coords(e);
        for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int, int, const LinkLimits&) { pass_seeds_.push_back(n); });
      }
    };
    // Copy 1 is not read again in this axis: its value feeds the midpoint only.
    for (Index e : c0.changed) c0.val[e] = 0.5f * (value(pos, b, 0, e) + value(pos, b, 1, e));
    changed_and_neighbours();
    ok &= pass(m, pos, b, 0, wall, true, pass_seeds_);
    changed_and_neighbours();
    ok &= pass(m, pos, b, 0, wall, false, pass_seeds_);
    for (Index e : c0.changed) {
      c0.flags[e] &= static_cast<std::uint8_t>(~kChanged);
      const float restored = c0.val[e];
      if (restored == pos.displacement(e)[b]) continue;
      pos.set_coordinate(e, b, restored);
      moved[grid.brick_of_index(e)] = 1;
      if (!moved_flag_[e]) {
        moved_flag_[e] = 1;
        moved_list_.push_back(e);
      }
    }
    c0.changed.clear();
  }
  if (record_moved_) record_moved_->insert(record_moved_->end(), moved_list_.begin(), moved_list_.end());
  else st.moved += static_cast<Index>(moved_list_.size());
  st.capped = st.capped || !ok;
  for (Index e : moved_list_) moved_flag_[e] = 0;
  moved_list_.clear();
}

}  // namespace hpcm::solver
