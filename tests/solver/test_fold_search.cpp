// The fold guard's search for folded cells in chunks (solver::find_fold_suspects and
// solver::find_folded_cells with a ParallelFor, which the CPU backend runs on its pool) finds
// the same suspects, the same folded cells and the same corners as the one-thread search,
// whatever order or threads run the chunks: a frame's result must not depend on them. And the
// search is complete: the cells around the links that may fold (column dominance below
// kFoldDominance) are every folded cell of the lattice.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "hpcm/state.hpp"
#include "solver/link_restore.hpp"
#include "restore_test_util.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;

namespace {

struct VectorAccess : solver::RestoreAccess {
  const std::vector<Vec3>& pos;
  explicit VectorAccess(const std::vector<Vec3>& p) : pos(p) {}
  Vec3 displacement(Index i) const override { return pos[static_cast<std::size_t>(i)]; }
  void set_coordinate(Index, int, float) override { ADD_FAILURE() << "the search must not move anything"; }
  bool fixed(Index) const override { return false; }
};

}  // namespace

TEST(FoldSearch, ChunksFindTheSameCellsAsOneThread) {
  const Model m = build_model(test::make_volume({40, 36, 30}, [](int x, int y, int) { return (x + y) % 5 < 2 ? 50.0f : -100.0f; }),
                              Params{});
  const std::size_t n = static_cast<std::size_t>(m.size());
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-0.7f, 0.7f);
  std::uniform_int_distribution<Index> pick(0, m.size() - 1);
  for (int trial = 0; trial < 4; ++trial) {
    // A smooth field with scattered kicks: many links that may fold, some cells folded.
    std::vector<Vec3> u(n, Vec3{});
    for (int k = 0; k < 1500 * (trial + 1); ++k) u[static_cast<std::size_t>(pick(rng))] = Vec3{jitter(rng), jitter(rng), jitter(rng)};
    const VectorAccess pos(u);
    std::vector<Index> elements;
    for (Index e = 0; e < m.size(); ++e)
      if (!(u[static_cast<std::size_t>(e)] == Vec3{})) elements.push_back(e);

    std::vector<Index> suspects, corners;
    solver::find_fold_suspects(m, elements, pos, suspects);
    const Index folded = solver::find_folded_cells(m, suspects, pos, corners);
    ASSERT_GT(suspects.size(), 1000u) << "trial " << trial;
    ASSERT_GT(folded, 0) << "trial " << trial << ": the case must fold cells to compare anything";

    for (const solver::ParallelFor& parallel : {solver::ParallelFor(test::reverse_order), solver::ParallelFor(test::two_threads)}) {
      std::vector<Index> s2, c2;
      solver::find_fold_suspects(m, elements, pos, s2, parallel);
      const Index f2 = solver::find_folded_cells(m, s2, pos, c2, parallel);
      EXPECT_EQ(s2, suspects) << "trial " << trial;
      EXPECT_EQ(f2, folded) << "trial " << trial;
      EXPECT_EQ(c2, corners) << "trial " << trial;
    }
  }
}

TEST(FoldSearch, SuspectsReachEveryFoldedCell) {
  const Model m = build_model(test::make_volume({24, 20, 16}, [](int x, int, int) { return x < 12 ? 50.0f : -100.0f; }),
                              Params{});
  const std::size_t n = static_cast<std::size_t>(m.size());
  std::vector<Index> all(n);
  for (Index e = 0; e < m.size(); ++e) all[static_cast<std::size_t>(e)] = e;
  std::mt19937 rng(11);
  std::uniform_int_distribution<Index> pick(0, m.size() - 1);
  Index folded_total = 0;
  // Kicks from small (cells near the edge of folding) to large, on a smooth shear that takes
  // every link close to its dominance margin: each folded cell must be found from the suspects.
  for (const float amplitude : {0.3f, 0.45f, 0.6f, 0.9f}) {
    for (const float shear : {0.0f, 0.3f, 0.45f}) {
      std::uniform_real_distribution<float> jitter(-amplitude, amplitude);
      std::vector<Vec3> u(n);
      for (Index e = 0; e < m.size(); ++e) {
        const Int3 c = m.coords(e);
        u[static_cast<std::size_t>(e)] = Vec3{shear * static_cast<float>(c.y), shear * static_cast<float>(c.z), 0.0f};
      }
      for (int k = 0; k < 400; ++k) {
        Vec3& v = u[static_cast<std::size_t>(pick(rng))];
        v = v + Vec3{jitter(rng), jitter(rng), jitter(rng)};
      }
      const VectorAccess pos(u);
      std::vector<Index> every_corner, suspects, corners;
      const Index every = solver::find_folded_cells(m, all, pos, every_corner);  // every cell tested
      solver::find_fold_suspects(m, all, pos, suspects);
      const Index found = suspects.empty() ? 0 : solver::find_folded_cells(m, suspects, pos, corners);
      EXPECT_EQ(found, every) << "amplitude " << amplitude << ", shear " << shear;
      EXPECT_EQ(corners, every_corner) << "amplitude " << amplitude << ", shear " << shear;
      EXPECT_LT(suspects.size(), n / 2) << "the test looks at a few cells, not all of them";
      folded_total += every;
    }
  }
  EXPECT_GT(folded_total, 100) << "the fields must fold cells to test anything";
}

// The shear cap keeps every link in its box at a column dominance of at least 0.02, so the
// guard never takes a link in its box for a suspect: at every corner of the box (the least
// spacing, the largest shear on both other axes, either sign), for tolerances across (0, 1].
TEST(FoldSearch, LinksInTheirBoxesAreNeverSuspects) {
  int corners = 0;
  for (float tau = 0.001f; tau <= 1.0f; tau += 0.001f) {
    const LinkLimits L = limits_from_tau(tau, 1.0f);
    for (int a = 0; a < 3; ++a)
      for (const float stretch : {L.min_stretch, L.max_stretch})
        for (const float s1 : {-L.shear, L.shear})
          for (const float s2 : {-L.shear, L.shear}) {
            Vec3 d{};
            d[a] = stretch;
            d[(a + 1) % 3] = s1;
            d[(a + 2) % 3] = s2;
            const Vec3 u_lo{0.3f, -0.2f, 0.1f};
            EXPECT_GE(column_dominance(u_lo, u_lo + d, a), 0.02f - 1e-5f) << "tau " << tau << ", axis " << a;
            EXPECT_FALSE(solver::may_fold(u_lo, u_lo + d, a)) << "tau " << tau << ", axis " << a;
            ++corners;
          }
  }
  EXPECT_GT(corners, 20000);
  // And a link sheared past its spacing is a suspect.
  EXPECT_TRUE(solver::may_fold(Vec3{}, Vec3{-0.5f, 0.3f, 0.25f}, 0));
}
