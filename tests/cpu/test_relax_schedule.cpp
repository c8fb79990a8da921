// The CPU relaxation's schedule skips work whose result is known: a cell (one brick column of
// one plane) is evaluated in a half-sweep only where it or a face neighbour changed, and a brick
// row's cells between its first and last active cell run through the kernel in one run. The
// result must be that of plain red-black sweeps over every element with the scalar rule: the
// schedule is an optimisation, not an approximation. Checked bit for bit on a CT-like phantom
// with scattered disturbances (rows of cells with active and quiet stretches), with one and two
// threads and every SIMD path this CPU runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "cpu/kernels.hpp"
#include "cpu/relax.hpp"
#include "cpu/storage.hpp"
#include "cpu/worker_pool.hpp"
#include "hpcm/phantom.hpp"
#include "solver/rules.hpp"

using namespace hpcm;

namespace {

struct Lattice {
  cpu::Storage st;
  cpu::RelaxContext ctx{};
};

void prepare(Lattice& l, const Model& m, const Params& p, const State& s, cpu::WorkerPool& pool) {
  l.st.load(m, s, pool);
  cpu::RelaxContext& c = l.ctx;
  c.lay = &l.st.lay;
  for (int a = 0; a < 3; ++a) {
    c.p[a] = l.st.p[a].data();
    c.link_tau[a] = l.st.link_tau[a].data();
  }
  c.weight = l.st.weight.data();
  c.flags = l.st.flags.data();
  c.time = l.st.time.data();
  c.model = &m;
  c.wall = solver::make_wall(m.dims, p.dynamics.margin);
  c.threshold = p.solver.relax_threshold;
  c.threshold_sq = cpu::squared_threshold(p.solver.relax_threshold);
  c.omega = p.solver.relax_omega;
}

std::vector<float> positions(const cpu::Storage& st) {
  std::vector<float> out;
  const Int3 d = st.lay.dims;
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) {
        const Index k = st.lay.at(x, y, z);
        for (int a = 0; a < 3; ++a) out.push_back(st.p[a][static_cast<std::size_t>(k)]);
      }
  return out;
}

}  // namespace

TEST(RelaxationSchedule, SparseScheduleEqualsDenseRedBlackSweeps) {
  PhantomOptions o;
  o.dims = {70, 44, 27};  // partial bricks on every axis, rows of 35 elements per colour
  Params p;
  const Model m = build_model(make_phantom(o), p);
  // Disturbances at a few places along x, y and z: the active region is a set of islands, so
  // brick rows hold active cells with quiet ones between them.
  State s = State::rest(m);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> U(-0.3f, 0.3f);
  const Int3 centres[] = {{5, 9, 5}, {30, 10, 6}, {61, 12, 20}, {22, 35, 14}, {50, 30, 3}};
  for (const Int3 c : centres)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Index i = m.index(c.x + dx, c.y + dy, c.z + dz);
          s.pos[static_cast<std::size_t>(i)] = s.pos[static_cast<std::size_t>(i)] + Vec3{U(rng), U(rng), U(rng)};
        }
  solver::BrickGrid grid;
  grid.init(m.dims, p.solver.brick_size);

  for (const int sweeps : {1, 3, 8}) {
    // The reference: every element of each colour, in turn, with the scalar rule.
    cpu::WorkerPool one(1);
    Lattice dense;
    prepare(dense, m, p, s, one);
    for (int sweep = 0; sweep < sweeps; ++sweep)
      for (int colour = 0; colour < 2; ++colour)
        for (int z = 0; z < m.dims.z; ++z)
          for (int y = 0; y < m.dims.y; ++y)
            for (int x = (colour + y + z) & 1; x < m.dims.x; x += 2) cpu::relax_element_scalar(dense.ctx, x, y, z);
    const std::vector<float> want = positions(dense.st);

    std::vector<std::string> paths = {"sse2"};
    if (cpu::cpu_has_avx2()) paths.push_back("avx2");
    if (cpu::cpu_has_avx512()) paths.push_back("avx512");
    for (const std::string& path : paths)
      for (const int threads : {1, 2}) {
        cpu::WorkerPool pool(threads);
        Lattice sparse;
        prepare(sparse, m, p, s, pool);
        std::vector<std::uint8_t> hot(static_cast<std::size_t>(grid.count), 0), touched = hot, worked = hot;
        for (std::size_t u = 0; u < s.pos.size(); ++u)
          if (!(s.pos[u] == m.rest(static_cast<Index>(u)))) hot[static_cast<std::size_t>(grid.brick_of_index(static_cast<Index>(u)))] = 1;
        Index hot_bricks = 0;
        for (std::uint8_t h : hot) hot_bricks += h;
        ASSERT_GE(hot_bricks, 5);
        cpu::Relaxation relaxation;
        relaxation.init(grid, cpu::select_kernels(path).relax);
        relaxation.run(sparse.ctx, sweeps, hot, touched, worked, pool);
        Index worked_bricks = 0;
        for (std::uint8_t w : worked) worked_bricks += w;
        if (sweeps <= 3) EXPECT_LT(worked_bricks, grid.count) << "the schedule must skip quiet bricks, or the test shows nothing";
        const std::vector<float> got = positions(sparse.st);
        ASSERT_EQ(got.size(), want.size());
        std::size_t first_diff = got.size();
        for (std::size_t i = 0; i < got.size() && first_diff == got.size(); ++i)
          if (std::memcmp(&got[i], &want[i], sizeof(float)) != 0) first_diff = i;
        EXPECT_EQ(first_diff, got.size()) << sweeps << " sweeps, " << path << ", " << threads
                                          << " threads: first differing coordinate " << first_diff;
      }
    // The disturbance must have moved elements that the first sweep did not reach.
    float moved = 0.0f;
    const std::vector<float> start = [&] {
      cpu::WorkerPool p1(1);
      Lattice l;
      prepare(l, m, p, s, p1);
      return positions(l.st);
    }();
    for (std::size_t i = 0; i < want.size(); ++i) moved = std::max(moved, std::fabs(want[i] - start[i]));
    EXPECT_GT(moved, 1e-3f) << sweeps << " sweeps: the relaxation must move something";
  }
}
