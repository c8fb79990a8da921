#include "cpu/link_check.hpp"

#include <algorithm>
#include <cstring>

#include "core/link_box.hpp"
#include "solver/restore.hpp"

namespace hpcm::cpu {

namespace {

typedef float f4 __attribute__((vector_size(16)));
constexpr int N = 4;

f4 load4(const float* p) {
  f4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
f4 vmax(f4 a, f4 b) { return a > b ? a : b; }
f4 vabs(f4 a) { return a < 0.0f ? -a : a; }

/// Largest violation of the link from (p, lo end) to (q, hi end) along axis a, per lane (the
/// arithmetic of link_violation; only compared against the tolerance here).
f4 link_excess(const f4 p[3], const f4 q[3], f4 tau, int a) {
  const f4 min_d = 1.0f - 0.8f * tau, max_d = 1.0f + tau;
  const f4 cap = 0.5f * (0.98f - 0.8f * tau);
  const f4 shear = tau < cap ? tau : cap;
  f4 v = f4{} + 0.0f;
  for (int b = 0; b < 3; ++b) {
    const f4 d = q[b] - p[b];
    const f4 e = b == a ? vmax(min_d - d, d - max_d) : vabs(d) - shear;
    v = vmax(v, e);
  }
  return v;
}

}  // namespace

void LinkCheck::run(const Storage& st, const solver::BrickGrid& grid, const std::vector<Index>& bricks,
                    const solver::Wall& wall, std::vector<Index>& seeds, RestoreStats& stats, WorkerPool& pool) {
  const Layout& L = st.lay;
  const int d[3] = {L.dims.x, L.dims.y, L.dims.z};
  const Index step[3] = {1, d[0], static_cast<Index>(d[0]) * d[1]};
  if (found_.size() < bricks.size()) found_.resize(bricks.size());
  partial_.assign(bricks.size(), RestoreStats{});
  pool.run(static_cast<std::int64_t>(bricks.size()), [&](std::int64_t item) {
    std::vector<Index>& out = found_[static_cast<std::size_t>(item)];
    RestoreStats& ps = partial_[static_cast<std::size_t>(item)];
    out.clear();
    Int3 lo, hi;
    grid.range(bricks[static_cast<std::size_t>(item)], lo, hi);
    // The exact check of one element, for the lanes the vector pass flags.
    auto check_element = [&](int x, int y, int z) {
      const Index k = L.at(x, y, z);
      const Vec3 pe{st.p[0][k], st.p[1][k], st.p[2][k]};
      const Index e = x + static_cast<Index>(d[0]) * (y + static_cast<Index>(d[1]) * z);
      const int c[3] = {x, y, z};
      bool seed_e = false;
      for (int a = 0; a < 3; ++a) {
        const float outside = std::max(wall.lo[a] - pe[a], pe[a] - wall.hi[a]);
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
    const f4 wlo[3] = {f4{} + wall.lo[0], f4{} + wall.lo[1], f4{} + wall.lo[2]};
    const f4 whi[3] = {f4{} + wall.hi[0], f4{} + wall.hi[1], f4{} + wall.hi[2]};
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int h = 0; h < 2; ++h) {
          // Elements x = 2j + h in [lo.x, hi.x); the vector pass covers those whose +x
          // neighbour exists (x + 1 < nx), the last one of the lattice row is checked exactly.
          const int j0 = lo.x / 2;                      // lo.x is even
          const int j1 = (hi.x - h + 1) / 2;
          const int jx = std::min(j1, (d[0] - h) / 2);  // 2j + h + 1 < nx
          const Index k0 = L.row_start(h, y, z);
          const Index ko = L.row_start(1 - h, y, z) + (h == 0 ? 0 : 1);  // +x neighbour of j
          const Index sy = L.width[h], sz = static_cast<Index>(L.width[h]) * d[1];
          const bool has_y = y + 1 < d[1], has_z = z + 1 < d[2];
          int j = j0;
          for (; j + N <= jx; j += N) {
            const Index k = k0 + j;
            const f4 p[3] = {load4(st.p[0].data() + k), load4(st.p[1].data() + k), load4(st.p[2].data() + k)};
            f4 worst = f4{} + 0.0f;
            for (int b = 0; b < 3; ++b) worst = vmax(worst, vmax(wlo[b] - p[b], p[b] - whi[b]));
            const Index kq[3] = {ko + j, k + sy, k + sz};
            const bool has[3] = {true, has_y, has_z};
            for (int a = 0; a < 3; ++a) {
              if (!has[a]) continue;
              const f4 q[3] = {load4(st.p[0].data() + kq[a]), load4(st.p[1].data() + kq[a]), load4(st.p[2].data() + kq[a])};
              worst = vmax(worst, link_excess(p, q, load4(st.link_tau[a].data() + k), a));
            }
            for (int l = 0; l < N; ++l)
              if (worst[l] > solver::kRestoreTolerance) check_element(2 * (j + l) + h, y, z);
          }
          for (; j < j1; ++j) check_element(2 * j + h, y, z);
        }
  });
  const std::size_t first = seeds.size();
  for (std::size_t item = 0; item < bricks.size(); ++item) {
    seeds.insert(seeds.end(), found_[item].begin(), found_[item].end());
    stats.violated_links += partial_[item].violated_links;
    stats.max_violation = std::max(stats.max_violation, partial_[item].max_violation);
  }
  std::sort(seeds.begin() + static_cast<std::ptrdiff_t>(first), seeds.end());
  seeds.erase(std::unique(seeds.begin() + static_cast<std::ptrdiff_t>(first), seeds.end()), seeds.end());
}

}  // namespace hpcm::cpu
