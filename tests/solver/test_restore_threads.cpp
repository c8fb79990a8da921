// The link restoration's two pass orders on two threads (LinkRestorer::set_parallel, which the
// CPU backend runs on its pool) give the same positions, bit for bit, as on one thread, and the
// same moved bricks and counts: each order has its own working state, and the second pass of
// each is seeded from that order's own first pass. Run by the ThreadSanitizer job.
#include <gtest/gtest.h>

#include <random>

#include "hpcm/state.hpp"
#include "solver/link_restore.hpp"
#include "restore_test_util.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;

namespace {

struct Outcome {
  std::vector<Vec3> pos;
  std::vector<std::uint8_t> moved;
  RestoreStats st;
};

std::vector<Index> violated(const Model& m, const solver::BrickGrid& grid, const solver::Wall& wall,
                            solver::RestoreAccess& acc, RestoreStats& found) {
  std::vector<Index> all_bricks(static_cast<std::size_t>(grid.count)), seeds;
  for (Index b = 0; b < grid.count; ++b) all_bricks[static_cast<std::size_t>(b)] = b;
  solver::find_violations(m, grid, all_bricks, acc, wall, seeds, found);
  return seeds;
}

Outcome restore_with(const Model& m, const solver::BrickGrid& grid, const solver::Wall& wall, std::vector<Vec3> pos,
                     const std::vector<std::uint8_t>& fixed, const solver::ParallelFor& parallel) {
  test::FixedVectorAccess acc(pos, fixed);
  solver::LinkRestorer restorer;
  restorer.init(m);
  if (parallel) restorer.set_parallel(parallel);
  Outcome out;
  out.moved.assign(static_cast<std::size_t>(grid.count), 0);
  // Twice, as a backend does frame after frame (the state each order keeps between calls, its
  // stamps and flags, must not change the second result): the same new kicks in every run.
  std::mt19937 rng(99);
  std::uniform_real_distribution<float> jitter(-0.3f, 0.3f);
  std::uniform_int_distribution<Index> pick(0, m.size() - 1);
  for (int call = 0; call < 2; ++call) {
    if (call == 1)
      for (int k = 0; k < 200; ++k) {
        Vec3& u = pos[static_cast<std::size_t>(pick(rng))];
        u = u + Vec3{jitter(rng), jitter(rng), jitter(rng)};
      }
    RestoreStats found;
    const std::vector<Index> seeds = violated(m, grid, wall, acc, found);
    EXPECT_GT(found.violated_links, 200) << "call " << call;
    restorer.restore(m, grid, seeds, acc, wall, out.moved, out.st);
  }
  out.pos = std::move(pos);
  return out;
}

}  // namespace

TEST(RestoreThreads, TwoPassOrdersOnTwoThreadsGiveTheSamePositions) {
  const Model m = build_model(test::make_volume({36, 30, 24}, [](int x, int y, int) { return (x + 2 * y) % 7 < 3 ? 50.0f : -100.0f; }),
                              Params{});
  solver::BrickGrid grid;
  grid.init(m.dims, 8);
  const solver::Wall wall = solver::make_wall(m.dims, 2.0f);
  const std::size_t n = static_cast<std::size_t>(m.size());
  std::mt19937 rng(5);
  std::uniform_int_distribution<Index> pick(0, m.size() - 1);
  for (int trial = 0; trial < 3; ++trial) {
    // A pull along y in a slab of columns, scattered kicks on every axis, a few FIXED elements:
    // links far outside their boxes on every axis, chains of moves along y.
    std::uniform_real_distribution<float> jitter(-0.4f, 0.4f);
    std::vector<Vec3> pos(n, Vec3{});
    std::vector<std::uint8_t> fixed(n, 0);
    for (Index e = 0; e < m.size(); ++e) {
      const Int3 c = m.coords(e);
      if (c.x >= 12 && c.x < 18 && c.z >= 8 && c.z < 14) pos[static_cast<std::size_t>(e)].y = -1.5f * static_cast<float>(trial + 1);
    }
    for (int k = 0; k < 300; ++k) {
      Vec3& u = pos[static_cast<std::size_t>(pick(rng))];
      u = u + Vec3{jitter(rng), jitter(rng), jitter(rng)};
    }
    for (int k = 0; k < 20; ++k) fixed[static_cast<std::size_t>(pick(rng))] = 1;
    const Outcome one = restore_with(m, grid, wall, pos, fixed, {});
    ASSERT_GT(one.st.moved, 1000) << "trial " << trial << ": the restoration must move elements to compare anything";
    EXPECT_LE(max_link_violation(m, one.pos), 1e-5f) << "trial " << trial;
    for (const solver::ParallelFor& parallel : {solver::ParallelFor(test::two_threads), solver::ParallelFor(test::reverse_order)}) {
      const Outcome other = restore_with(m, grid, wall, pos, fixed, parallel);
      EXPECT_EQ(other.st.moved, one.st.moved) << "trial " << trial;
      EXPECT_EQ(other.st.capped, one.st.capped) << "trial " << trial;
      EXPECT_EQ(other.moved, one.moved) << "trial " << trial;
      ASSERT_EQ(other.pos.size(), one.pos.size());
      std::size_t differ = 0;
      for (std::size_t i = 0; i < n; ++i) differ += !(other.pos[i] == one.pos[i]);
      EXPECT_EQ(differ, 0u) << "trial " << trial << ": elements placed differently";
    }
  }
}
