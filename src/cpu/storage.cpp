#include "cpu/storage.hpp"

#include <cstdint>
#include <limits>

#include "solver/rules.hpp"

namespace hpcm::cpu {

namespace {

/// f(u, k) for every element, u its linear index and k its storage index; planes on the
/// backend's threads (not OpenMP: this runs every frame the positions are read, and OpenMP's
/// idle threads would spin on beside the simulation's, core/parallel.hpp).
template <class F>
void for_each_element(const Layout& lay, WorkerPool& pool, F f) {
  const int nx = lay.dims.x, ny = lay.dims.y;
  pool.run(lay.dims.z, [&](std::int64_t zz) {
    const int z = static_cast<int>(zz);
    for (int y = 0; y < ny; ++y) {
      const Index i0 = static_cast<Index>(nx) * (y + static_cast<Index>(ny) * z);
      for (int x = 0; x < nx; ++x) f(static_cast<std::size_t>(i0 + x), static_cast<std::size_t>(lay.at(x, y, z)));
    }
  });
}

/// f(u, k) for every element of the listed bricks, a brick per work item.
template <class F>
void for_each_element_of(const Layout& lay, const solver::BrickGrid& grid, const std::vector<Index>& bricks,
                         WorkerPool& pool, F f) {
  const int nx = lay.dims.x, ny = lay.dims.y;
  pool.run(static_cast<std::int64_t>(bricks.size()), [&](std::int64_t j) {
    Int3 lo, hi;
    grid.range(bricks[static_cast<std::size_t>(j)], lo, hi);
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y) {
        const Index i0 = static_cast<Index>(nx) * (y + static_cast<Index>(ny) * z);
        for (int x = lo.x; x < hi.x; ++x) f(static_cast<std::size_t>(i0 + x), static_cast<std::size_t>(lay.at(x, y, z)));
      }
  });
}

}  // namespace

void Storage::load(const Model& m, const State& s, WorkerPool& pool) {
  lay.init(m.dims);
  const std::size_t np = static_cast<std::size_t>(lay.span) + kPad;
  // Array starts 7 cache lines apart (distinct sets for 9 arrays and more).
  int lines = 0;
  auto next = [&lines] { return 7 * lines++; };
  for (int a = 0; a < 3; ++a) {
    p[a].assign(np, 0.0f, next());
    q[a].assign(np, 0.0f, next());
    v[a].assign(np, 0.0f, next());
    link_tau[a].assign(np, 0.0f, next());
  }
  time.assign(np, std::numeric_limits<float>::infinity(), next());
  weight.assign(np, 1.0f, next());
  tissue.assign(np, 0, next());
  stat_class.assign(np, kTissueCount, next());
  flags.assign(np, kFixed, next());  // padding and stagger gaps never move
  for_each_element(lay, pool, [&](std::size_t u, std::size_t k) {
    for (int a = 0; a < 3; ++a) {
      p[a][k] = q[a][k] = s.disp[u][a];  // invariant between frames: X- == X
      v[a][k] = s.vel[u][a];
      link_tau[a][k] = m.link_tau[m.link_index[a][u]];
    }
    weight[k] = solver::relax_weight(m.tau[u]);
    tissue[k] = m.tissue[u];
    stat_class[k] = m.counted(static_cast<Index>(u)) ? m.tissue[u] : kTissueCount;
    flags[k] = (s.flags[u] & kFixed) ? 0 : s.flags[u];  // the FIXED set comes with the Control (install_fixed)
  });
}

void Storage::store_displacements(std::vector<Vec3>& disp, WorkerPool& pool) const {
  disp.resize(static_cast<std::size_t>(lay.size));
  for_each_element(lay, pool, [&](std::size_t u, std::size_t k) { disp[u] = Vec3{p[0][k], p[1][k], p[2][k]}; });
}

void Storage::store_state(State& s, WorkerPool& pool) const {
  store_displacements(s.disp, pool);
  const std::size_t n = static_cast<std::size_t>(lay.size);
  s.vel.resize(n);
  s.time.resize(n);
  s.flags.resize(n);
  for_each_element(lay, pool, [&](std::size_t u, std::size_t k) {
    s.vel[u] = Vec3{v[0][k], v[1][k], v[2][k]};
    s.time[u] = time[k];
    s.flags[u] = flags[k];
  });
}

void Storage::store_displacements(std::vector<Vec3>& disp, const solver::BrickGrid& grid,
                                  const std::vector<Index>& bricks, WorkerPool& pool) const {
  for_each_element_of(lay, grid, bricks, pool,
                      [&](std::size_t u, std::size_t k) { disp[u] = Vec3{p[0][k], p[1][k], p[2][k]}; });
}

void Storage::store_state(State& s, const solver::BrickGrid& grid, const std::vector<Index>& bricks,
                          WorkerPool& pool) const {
  for_each_element_of(lay, grid, bricks, pool, [&](std::size_t u, std::size_t k) {
    s.disp[u] = Vec3{p[0][k], p[1][k], p[2][k]};
    s.vel[u] = Vec3{v[0][k], v[1][k], v[2][k]};
    s.time[u] = time[k];
    s.flags[u] = flags[k];
  });
}

}  // namespace hpcm::cpu
