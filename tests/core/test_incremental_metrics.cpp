// IncrementalMetrics: the integrity metrics of a sequence of displacement fields, recomputed only
// in the blocks around elements that changed, must equal the whole-lattice functions exactly
// (max_link_violation, cell_jacobian: value and folded count) after every change, wherever the
// change lies: inside a block, on a block's lower face (whose links and cells the block below
// owns), on the lattice's border, and on a lattice whose size is not a multiple of the block.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "hpcm/phantom.hpp"
#include "hpcm/state.hpp"

using namespace hpcm;

namespace {

void expect_same(IncrementalMetrics& links, IncrementalMetrics& cells, const Model& m, const std::vector<Vec3>& u,
                 const char* what) {
  EXPECT_EQ(links.max_link_violation(m, u), max_link_violation(m, u)) << what;
  const CellJacobianStats a = cells.cell_jacobian(m, u), b = cell_jacobian(m, u);
  EXPECT_EQ(a.min_det, b.min_det) << what;
  EXPECT_EQ(a.folded, b.folded) << what;
  EXPECT_EQ(a.cells, b.cells) << what;
}

}  // namespace

TEST(IncrementalMetrics, EqualTheWholeLatticeFunctionsOnEveryChange) {
  PhantomOptions o;
  o.dims = {27, 19, 13};  // not a multiple of the 8-element block on any axis
  const Model m = build_model(make_phantom(o), Params{});
  std::vector<Vec3> u(static_cast<std::size_t>(m.size()));
  IncrementalMetrics links, cells;
  expect_same(links, cells, m, u, "rest");

  // An element on the lower face of block (1, 0, 0) (x = 8) pushed back onto its -x neighbour:
  // the link 7 -> 8 and the cells with lower corner x = 7 belong to block (0, 0, 0).
  u[static_cast<std::size_t>(m.index(8, 5, 5))] = {-1.2f, 0.0f, 0.0f};
  expect_same(links, cells, m, u, "block face");
  EXPECT_GT(max_link_violation(m, u), 0.1f) << "the case must violate a link";
  EXPECT_GT(cell_jacobian(m, u).folded, 0) << "and fold a cell";
  u[static_cast<std::size_t>(m.index(8, 5, 5))] = {};  // back: the violation must go with it
  expect_same(links, cells, m, u, "block face undone");
  EXPECT_EQ(max_link_violation(m, u), 0.0f);

  std::mt19937 rng(20261128);
  std::uniform_int_distribution<int> px(0, o.dims.x - 1), py(0, o.dims.y - 1), pz(0, o.dims.z - 1), size(0, 3);
  std::uniform_real_distribution<float> small(-0.05f, 0.05f), large(-1.2f, 1.2f);
  int violated = 0, folded = 0;
  for (int step = 0; step < 300; ++step) {
    // A small region moves (some steps nothing does: the cached values must hold).
    if (step % 7 != 3) {
      const int x0 = px(rng), y0 = py(rng), z0 = pz(rng), r = size(rng);
      const bool big = step % 5 == 0;
      for (int z = z0; z <= std::min(z0 + r, o.dims.z - 1); ++z)
        for (int y = y0; y <= std::min(y0 + r, o.dims.y - 1); ++y)
          for (int x = x0; x <= std::min(x0 + r, o.dims.x - 1); ++x) {
            Vec3& e = u[static_cast<std::size_t>(m.index(x, y, z))];
            e = step % 11 == 0 ? Vec3{} : e + (big ? Vec3{large(rng), large(rng), large(rng)} : Vec3{small(rng), small(rng), small(rng)});
          }
    }
    expect_same(links, cells, m, u, "random step");
    violated += max_link_violation(m, u) > 0.0f;
    folded += cell_jacobian(m, u).folded > 0;
  }
  EXPECT_GT(violated, 10) << "the sequence must reach violated links";
  EXPECT_GT(folded, 10) << "and folded cells";
  EXPECT_LT(folded, 300);
}

TEST(IncrementalMetrics, ResetForNewLinksAndANewLatticeSize) {
  PhantomOptions o;
  o.dims = {20, 16, 12};
  const Model m = build_model(make_phantom(o), Params{});
  Params stiff;
  stiff.tissue.t1 = -900.0f;  // other classes: other link boxes on the same lattice
  const Model n = build_model(make_phantom(o), stiff);
  std::vector<Vec3> u(static_cast<std::size_t>(m.size()));
  for (std::size_t i = 0; i < u.size(); i += 3) u[i] = {0.3f, -0.2f, 0.1f};
  IncrementalMetrics links;
  EXPECT_EQ(links.max_link_violation(m, u), max_link_violation(m, u));
  links.reset();
  EXPECT_EQ(links.max_link_violation(n, u), max_link_violation(n, u));
  // Another lattice: its own blocks, without a reset.
  PhantomOptions p;
  p.dims = {9, 9, 9};
  const Model k = build_model(make_phantom(p), Params{});
  std::vector<Vec3> v(static_cast<std::size_t>(k.size()), Vec3{0.0f, 0.4f, 0.0f});
  v[0] = {0.5f, 0.0f, 0.0f};
  EXPECT_EQ(links.max_link_violation(k, v), max_link_violation(k, v));
  EXPECT_GT(max_link_violation(k, v), 0.0f);
}
