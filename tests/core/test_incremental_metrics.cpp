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
  o.dims = {27, 19, 13};  // not a multiple of the 4-element block on any axis
  const Model m = build_model(make_phantom(o), Params{});
  std::vector<Vec3> u(static_cast<std::size_t>(m.size()));
  IncrementalMetrics links, cells;
  expect_same(links, cells, m, u, "rest");

  // An element on the lower face of block (2, 1, 1) (x = 8) pushed back onto its -x neighbour:
  // the link 7 -> 8 and the cells with lower corner x = 7 belong to block (1, 1, 1).
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

// The cell determinants themselves, against fields whose answer is known: a linear map u = (A -
// I) x has det A at every corner of every cell (the reported minimum starts at 1, so A shrinks);
// one element pushed through its +x neighbour folds exactly the four cells in which it is on the
// low-x side (their +x edge turns back), and no other.
TEST(CellJacobian, LinearMapsGiveTheirDeterminantAndOnePushedElementFoldsFourCells) {
  PhantomOptions o;
  o.dims = {11, 9, 8};
  const Model m = build_model(make_phantom(o), Params{});
  const Index cells = static_cast<Index>(10) * 8 * 7;
  std::vector<Vec3> u(static_cast<std::size_t>(m.size()));
  auto linear = [&](const double a[3][3]) {
    for (int z = 0; z < o.dims.z; ++z)
      for (int y = 0; y < o.dims.y; ++y)
        for (int x = 0; x < o.dims.x; ++x) {
          const double p[3] = {double(x), double(y), double(z)};
          double q[3];
          for (int r = 0; r < 3; ++r) q[r] = a[r][0] * p[0] + a[r][1] * p[1] + a[r][2] * p[2] - p[r];
          u[static_cast<std::size_t>(m.index(x, y, z))] = {float(q[0]), float(q[1]), float(q[2])};
        }
  };
  const double shear[3][3] = {{0.9, 0.2, 0.0}, {0.0, 0.8, 0.1}, {0.05, 0.0, 1.1}};
  linear(shear);  // det = 0.9 * (0.8 * 1.1 - 0) - 0.2 * (0 - 0.1 * 0.05) = 0.793
  CellJacobianStats s = cell_jacobian(m, u);
  EXPECT_NEAR(s.min_det, 0.793, 1e-5);
  EXPECT_EQ(s.folded, 0);
  EXPECT_EQ(s.cells, cells);
  const double mirror[3][3] = {{-1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
  linear(mirror);  // every corner of every cell has det -1
  s = cell_jacobian(m, u);
  EXPECT_EQ(s.min_det, -1.0f);
  EXPECT_EQ(s.folded, cells);

  std::fill(u.begin(), u.end(), Vec3{});
  u[static_cast<std::size_t>(m.index(5, 4, 3))] = {1.5f, 0.0f, 0.0f};  // through (6, 4, 3)
  s = cell_jacobian(m, u);
  EXPECT_EQ(s.folded, 4) << "the four cells with (5, 4, 3) as a low-x corner";
  EXPECT_LT(s.min_det, 0.0f);
}

// Against a reference written from the definition on a random field that folds some cells: at
// each corner of each cell, the three cell edges through the corner (unit rest edge plus the
// difference of the displacements at its ends), their determinant in double.
TEST(CellJacobian, EqualsTheDefinitionOnARandomField) {
  PhantomOptions o;
  o.dims = {12, 10, 9};
  const Model m = build_model(make_phantom(o), Params{});
  std::mt19937 rng(1128);
  std::uniform_real_distribution<float> amp(-0.45f, 0.45f);
  std::vector<Vec3> u(static_cast<std::size_t>(m.size()));
  for (Vec3& e : u) e = {amp(rng), amp(rng), amp(rng)};
  auto at = [&](int x, int y, int z) { return u[static_cast<std::size_t>(m.index(x, y, z))]; };
  double min_det = 1.0;
  Index folded = 0;
  for (int z = 0; z + 1 < o.dims.z; ++z)
    for (int y = 0; y + 1 < o.dims.y; ++y)
      for (int x = 0; x + 1 < o.dims.x; ++x) {
        double cell_min = 1e30;
        for (int k = 0; k < 2; ++k)
          for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i) {
              const Vec3 ex = at(x + 1, y + j, z + k) - at(x, y + j, z + k);
              const Vec3 ey = at(x + i, y + 1, z + k) - at(x + i, y, z + k);
              const Vec3 ez = at(x + i, y + j, z + 1) - at(x + i, y + j, z);
              const double a[3][3] = {{1.0 + ex.x, ey.x, ez.x}, {ex.y, 1.0 + ey.y, ez.y}, {ex.z, ey.z, 1.0 + ez.z}};
              const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                                 a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                                 a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
              cell_min = std::min(cell_min, det);
            }
        min_det = std::min(min_det, cell_min);
        folded += cell_min <= 0.0;
      }
  ASSERT_GT(folded, 0) << "the field must fold some cells";
  ASSERT_LT(folded, static_cast<Index>(11) * 9 * 8) << "and leave others";
  const CellJacobianStats s = cell_jacobian(m, u);
  EXPECT_NEAR(s.min_det, min_det, 1e-6);
  EXPECT_EQ(s.folded, folded);
}
