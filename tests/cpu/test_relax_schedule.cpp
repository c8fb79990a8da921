// The CPU relaxation's schedule skips work whose result is known: a cell (one brick column of
// one plane) is evaluated in a half-sweep only where it or a face neighbour changed, and a brick
// row's cells between its first and last active cell run through the kernel in one run. The
// result must be that of plain red-black sweeps over every element with the scalar rule: the
// schedule is an optimisation, not an approximation. Checked bit for bit on a CT-like phantom
// with scattered disturbances (rows of cells with active and quiet stretches), with one and two
// threads and every SIMD path this CPU runs.
#include <gtest/gtest.h>

#include <algorithm>
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

/// The storage of state s and a relaxation context over it (the backend's settings).
struct Lattice {
  cpu::Storage st;
  cpu::RelaxContext ctx{};
  Lattice(const Model& m, const Params& p, const State& s, cpu::WorkerPool& pool) {
    st.load(m, s, pool);
    ctx = cpu::make_relax_context(st, m, solver::make_wall(m.dims, p.dynamics.margin), p.solver);
  }
};

/// Displacements in linear order (Storage::store_displacements).
std::vector<Vec3> positions(const cpu::Storage& st, cpu::WorkerPool& pool) {
  std::vector<Vec3> out;
  st.store_displacements(out, pool);
  return out;
}

/// The sparse schedule against dense sweeps on a phantom of `dims` disturbed around `centres`.
void check_schedule(Int3 dims, const std::vector<Int3>& centres) {
  SCOPED_TRACE(std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" + std::to_string(dims.z));
  PhantomOptions o;
  o.dims = dims;
  Params p;
  const Model m = build_model(make_phantom(o), p);
  // Disturbances at a few places along x, y and z: the active region is a set of islands, so
  // brick rows hold active cells with quiet ones between them.
  State s = State::rest(m);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> U(-0.3f, 0.3f);
  for (const Int3 c : centres)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Index i = m.index(c.x + dx, c.y + dy, c.z + dz);
          s.disp[static_cast<std::size_t>(i)] = s.disp[static_cast<std::size_t>(i)] + Vec3{U(rng), U(rng), U(rng)};
        }
  solver::BrickGrid grid;
  grid.init(m.dims, p.solver.brick_size);

  // The bricks holding the disturbance: where the relaxation starts (hot), as the backend marks them.
  std::vector<std::uint8_t> start_hot(static_cast<std::size_t>(grid.count), 0);
  for (std::size_t u = 0; u < s.disp.size(); ++u)
    if (!(s.disp[u] == Vec3{})) start_hot[static_cast<std::size_t>(grid.brick_of_index(static_cast<Index>(u)))] = 1;
  ASSERT_GE(std::count(start_hot.begin(), start_hot.end(), 1), 5);
  cpu::WorkerPool one(1);
  const std::vector<Vec3> start = positions(Lattice(m, p, s, one).st, one);
  std::vector<std::string> paths = {"sse2"};
  if (cpu::cpu_has_avx2()) paths.push_back("avx2");
  if (cpu::cpu_has_avx512()) paths.push_back("avx512");

  for (const int sweeps : {1, 3, 8}) {
    // The reference: every element of each colour, in turn, with the scalar rule.
    Lattice dense(m, p, s, one);
    for (int sweep = 0; sweep < sweeps; ++sweep)
      for (int colour = 0; colour < 2; ++colour)
        for (int z = 0; z < m.dims.z; ++z)
          for (int y = 0; y < m.dims.y; ++y)
            for (int x = (colour + y + z) & 1; x < m.dims.x; x += 2) cpu::relax_element_scalar(dense.ctx, x, y, z);
    const std::vector<Vec3> want = positions(dense.st, one);
    float moved = 0.0f;
    for (std::size_t i = 0; i < want.size(); ++i) moved = std::max(moved, norm(want[i] - start[i]));
    EXPECT_GT(moved, 1e-3f) << sweeps << " sweeps: the relaxation must move something";

    for (const std::string& path : paths)
      for (const int threads : {1, 2}) {
        cpu::WorkerPool pool(threads);
        Lattice sparse(m, p, s, pool);
        std::vector<std::uint8_t> hot = start_hot, touched(start_hot.size(), 0), worked(start_hot.size(), 0);
        cpu::Relaxation relaxation;
        relaxation.init(grid, cpu::select_kernels(path).relax);
        relaxation.run(sparse.ctx, sweeps, hot, touched, worked, pool);
        if (sweeps <= 3)
          EXPECT_LT(std::count(worked.begin(), worked.end(), 1), grid.count) << "the schedule must skip quiet bricks, or the test shows nothing";
        const std::vector<Vec3> got = positions(sparse.st, pool);
        ASSERT_EQ(got.size(), want.size());
        std::size_t first_diff = got.size();
        for (std::size_t i = 0; i < got.size() && first_diff == got.size(); ++i)
          if (std::memcmp(&got[i], &want[i], sizeof(Vec3)) != 0) first_diff = i;
        EXPECT_EQ(first_diff, got.size()) << sweeps << " sweeps, " << path << ", " << threads
                                          << " threads: first differing element " << first_diff;
      }
  }
}

}  // namespace

TEST(RelaxationSchedule, SparseScheduleEqualsDenseRedBlackSweeps) {
  // Partial bricks on every axis, rows of 35 elements per colour.
  check_schedule({70, 44, 27}, {{5, 9, 5}, {30, 10, 6}, {61, 12, 20}, {22, 35, 14}, {50, 30, 3}});
  // An odd width: rows of 33 and 32 elements, the last brick column one element wide (x = 64,
  // the even colour only), disturbed at both ends of the rows.
  check_schedule({65, 41, 19}, {{1, 9, 5}, {63, 20, 10}, {30, 12, 16}, {63, 35, 3}});
}
