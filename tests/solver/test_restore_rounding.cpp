// The link restoration far from the lattice origin. Positions are displacements from rest
// (u = X - X0), so the float step of a coordinate no longer grows with the distance from the
// origin: the restoration rounds every box limit to nearest and leaves each link it touches
// within half a float step of the displacements involved, at any x. Before (absolute
// positions), a restored link could stay half a float step of the coordinate outside: 1.52e-5
// at y = 490 and 3.05e-5 at y = 588, beyond the 1e-5 integrity check, which needed inward
// rounding and a slack reserve in the tool limit (docs/solver.md, "Displacements from rest").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <random>

#include "hpcm/simulation.hpp"
#include "hpcm/state.hpp"
#include "solver/link_restore.hpp"
#include "restore_test_util.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;

namespace {

struct VectorAccess : solver::RestoreAccess {
  std::vector<Vec3>& pos;
  explicit VectorAccess(std::vector<Vec3>& p) : pos(p) {}
  Vec3 displacement(Index i) const override { return pos[static_cast<std::size_t>(i)]; }
  void set_coordinate(Index i, int axis, float value) override { pos[static_cast<std::size_t>(i)][axis] = value; }
  bool fixed(Index) const override { return false; }
};

struct ScatterCase {
  const char* name;
  int length;      ///< bar of length x 2 x 2 elements
  int from, to;    ///< elements with x in [from, to) are scattered
  bool all_axes;   ///< scattered on y and z too (else along x only)
};

void PrintTo(const ScatterCase& c, std::ostream* os) { *os << c.name; }

}  // namespace

class RestoreRounding : public ::testing::TestWithParam<ScatterCase> {};

// A bar of muscle and fat; the elements in [from, to) are scattered by up to 0.3 cells (far
// outside their boxes), then restored. Every link along the bar must end within half a float
// step of its displacements (below 0.3 cells: 1.5e-8), wherever along the bar it lies.
TEST_P(RestoreRounding, ScatteredLinksEndExactlyInTheirBoxes) {
  const ScatterCase sc = GetParam();
  const Model m = build_model(test::make_volume({sc.length, 2, 2}, [](int x, int, int) { return x % 7 < 3 ? 50.0f : -100.0f; }),
                              Params{});
  solver::BrickGrid grid;
  grid.init(m.dims, 8);
  const solver::Wall wall = solver::make_wall(m.dims, 2.0f);
  // Displacements below 1 (scatter 0.3 plus a link's slack): half a float step is below 6e-8.
  const float allowed = 6e-8f;
  float worst = 0;
  for (unsigned seed = 1; seed <= 200; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> jitter(-0.3f, 0.3f);
    std::vector<Vec3> pos(static_cast<std::size_t>(m.size()));
    std::vector<Index> seeds;
    for (Index i = 0; i < m.size(); ++i) {
      pos[static_cast<std::size_t>(i)] = Vec3{};
      if (m.coords(i).x >= sc.from && m.coords(i).x < sc.to) {
        for (int b = 0; b < (sc.all_axes ? 3 : 1); ++b) pos[static_cast<std::size_t>(i)][b] += jitter(rng);
        seeds.push_back(i);
      }
    }
    ASSERT_GT(max_link_violation(m, pos), 0.1f);
    VectorAccess acc(pos);
    solver::LinkRestorer restorer;
    restorer.init(m);
    std::vector<std::uint8_t> moved(static_cast<std::size_t>(grid.count), 0);
    RestoreStats st;
    restorer.restore(m, grid, seeds, acc, wall, moved, st);
    EXPECT_GT(st.moved, 0);
    const float v = max_link_violation(m, pos);
    worst = std::max(worst, v);
    EXPECT_LE(v, allowed) << "seed " << seed;
  }
  std::printf("%s: largest link violation after restoration over 200 scatters: %.3g\n", sc.name, worst);
}

INSTANTIATE_TEST_SUITE_P(
    Bars, RestoreRounding,
    ::testing::Values(ScatterCase{"beyond128", 200, 130, 190, false}, ScatterCase{"across128", 200, 100, 160, true},
                      ScatterCase{"across256", 320, 230, 290, true}, ScatterCase{"beyond512", 620, 530, 600, true}),
    [](const ::testing::TestParamInfo<ScatterCase>& i) { return std::string(i.param.name); });

// A pull at the tool limit far from the origin: fat between the tool and an anchored bone plate
// 6 cells beyond it is stretched to its slack, so the chain's links are at the edge of their
// boxes. Every frame's ChainMail stage must leave every link within the restoration's
// tolerance.
TEST(RestoreRoundingPull, PullAtTheToolLimitFarFromTheOrigin) {
  for (int length : {152, 300, 560}) {
    const int plate = length - 6, grab = length - 12;
    const Volume v = test::make_volume({length, 9, 9}, [plate](int x, int, int) { return x >= plate ? 700.0f : -100.0f; });
    float worst = 0;
    for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic}) {
      Params p;
      p.dynamics.mode = mode;
      const Model m = build_model(v, p);
      Simulation sim(m, p);
      sim.grab(m.index(grab, 4, 4), 1.5f);
      StepOptions opt;
      opt.link_violation = true;
      bool limited = false;
      for (int f = 1; f <= 40; ++f) {
        if (f <= 20) sim.move_tool(Vec3{0.15f * float(f), 0.05f * float(f), 0.0f});
        if (f == 31) sim.release();
        const FrameReport r = sim.step(opt);
        limited = limited || r.tool_limited;
        worst = std::max(worst, r.max_link_violation);
        EXPECT_LE(r.max_link_violation, solver::kRestoreTolerance)
            << "length " << length << " mode " << static_cast<int>(mode) << " frame " << f;
      }
      EXPECT_TRUE(limited) << "the pull must reach the tool limit (length " << length << ")";
    }
    std::printf("bar of length %d: largest link violation after the ChainMail stage: %.3g\n", length, worst);
  }
}

// The DICOM series at f = 2 (256 x 256 x 10), condition B, pulled to the tool limit: a chain from a
// grabbed (FIXED) element stretched to its slack, whose next link the stage left outside its box
// by less than the restoration's tolerance. With inward rounding on absolute coordinates, the
// restoration's last one-sided pass "restored" the untouched link by raising its element a float
// step into the grabbed element's box: 1.7e-5 outside. Here the same geometry along x (a 200-cell
// bar, displacements near -1.5 around x = 80): g (FIXED) -> A (at g's bound) -> B (up to 4e-6
// beyond A's bound), and a displaced element D beside A for the restoration to move. Every link
// must end within the tolerance.
TEST(RestoreRoundingPull, ChainAtTheToolLimitWithALinkTheStageLeftWithinTheTolerance) {
  const int gx = 80;
  int cases = 0;
  float worst = 0;
  // The links g-A and A-B differ in tolerance (HU rising along the bar): the float steps by
  // which their stretch limits are missed differ too. The slopes vary both, the grab positions g.
  for (int t = 0; t < 40; ++t) {
    Params p = test::uniform_params(0.2f, 0.5f);
    p.material.points = {{-1000.0f, 0.15f, 0.5f}, {1000.0f, 0.35f, 0.5f}};
    const float slope = 7.0f + 3.1f * float(t);  // HU per cell
    const Model m = build_model(
        test::make_volume({200, 2, 1}, [slope](int x, int, int) { return std::clamp(slope * float(x - gx), -1000.0f, 1000.0f); }), p);
    solver::BrickGrid grid;
    grid.init(m.dims, 8);
    const solver::Wall wall = solver::make_wall(m.dims, 2.0f);
    const LinkLimits& L = m.link(0, m.index(gx, 0, 0));
    const LinkLimits& LB = m.link(0, m.index(gx + 1, 0, 0));
    for (int k = 0; k < 10; ++k) {
      const float g = -1.5f + 1e-3f * float(k);  // g's displacement
      // A: g's upper bound on its neighbour (the tool limit stretches the link to its slack).
      float a = solver::link_bound(g, L, 0, +1, 0, true);
      while (link_violation(Vec3{g, 0, 0}, Vec3{a, 0, 0}, L, 0) > 0.0f) a = std::nextafter(a, -INFINITY);
      // B: the stage's nearest rounding left the link A-B outside its box, within the tolerance.
      float b = a + LB.max_stretch;
      while (link_violation(Vec3{a, 0, 0}, Vec3{b, 0, 0}, LB, 0) == 0.0f) b = std::nextafter(b, INFINITY);
      if (link_violation(Vec3{a, 0, 0}, Vec3{b, 0, 0}, LB, 0) > solver::kRestoreTolerance) continue;
      ++cases;
      std::vector<Vec3> pos(static_cast<std::size_t>(m.size()));
      std::vector<std::uint8_t> fixed(static_cast<std::size_t>(m.size()), 0);
      for (Index i = 0; i < m.size(); ++i) {
        const Int3 c = m.coords(i);
        // Left of g: shifted rigidly with it; right of A: B and the rest at rest spacing. Row 1
        // alike, its part right of D 0.01 lower (no link there left outside its box).
        const float right = c.y == 0 ? b : b - 0.01f;
        const float u = c.x <= gx ? g : (c.x == gx + 1 ? a : right);
        pos[static_cast<std::size_t>(i)] = Vec3{u, 0.0f, 0.0f};
        if (c.x == gx) fixed[static_cast<std::size_t>(i)] = 1;
      }
      // D, beside A: 0.01 beyond its grabbed neighbour's box. The restoration lowers it back to
      // the bound (A's coordinate) and then looks at its neighbours, A among them.
      pos[static_cast<std::size_t>(m.index(gx + 1, 1, 0))].x += 0.01f;
      test::FixedVectorAccess acc(pos, fixed);
      std::vector<Index> all(static_cast<std::size_t>(grid.count));
      for (Index i = 0; i < grid.count; ++i) all[static_cast<std::size_t>(i)] = i;
      std::vector<Index> seeds;
      RestoreStats st;
      solver::find_violations(m, grid, all, acc, wall, seeds, st);
      ASSERT_FALSE(seeds.empty());
      solver::LinkRestorer restorer;
      restorer.init(m);
      std::vector<std::uint8_t> moved(static_cast<std::size_t>(grid.count), 0);
      restorer.restore(m, grid, seeds, acc, wall, moved, st);
      EXPECT_EQ(pos[static_cast<std::size_t>(m.index(gx, 0, 0))].x, g) << "a FIXED element moved";
      const float v = max_link_violation(m, pos);
      worst = std::max(worst, v);
      EXPECT_LE(v, solver::kRestoreTolerance) << "slope " << slope << ", g = " << g;
    }
  }
  EXPECT_GT(cases, 100);
  std::printf("%d chains: largest link violation after restoration %.3g\n", cases, worst);
}

// Every restoration pass is capped (kRestoreVisitsPerElement visits per lattice element) and a
// pass that reaches its cap says so (RestoreStats::capped, FrameReport::restore_converged). The
// scattered bar needs a few visits per element: with the default cap it finishes, with a cap of
// one visit per element a pass stops early and is reported; either way restore() returns.
TEST(RestoreCap, APassThatReachesItsCapStopsAndSaysSo) {
  const Model m = build_model(test::make_volume({64, 2, 2}, [](int x, int, int) { return x % 7 < 3 ? 50.0f : -100.0f; }), Params{});
  solver::BrickGrid grid;
  grid.init(m.dims, 8);
  const solver::Wall wall = solver::make_wall(m.dims, 2.0f);
  for (int cap : {solver::kRestoreVisitsPerElement, 1}) {
    std::mt19937 rng(4);
    std::uniform_real_distribution<float> jitter(-0.4f, 0.4f);
    std::vector<Vec3> pos(static_cast<std::size_t>(m.size()));
    std::vector<Index> seeds;
    for (Index i = 0; i < m.size(); ++i) {
      for (int b = 0; b < 3; ++b) pos[static_cast<std::size_t>(i)][b] = jitter(rng);
      seeds.push_back(i);
    }
    VectorAccess acc(pos);
    solver::LinkRestorer restorer;
    restorer.init(m);
    restorer.set_visits_per_element(cap);
    std::vector<std::uint8_t> moved(static_cast<std::size_t>(grid.count), 0);
    RestoreStats st;
    restorer.restore(m, grid, seeds, acc, wall, moved, st);
    if (cap == 1) {
      EXPECT_TRUE(st.capped) << "one visit per element cannot restore a lattice scattered everywhere";
    } else {
      EXPECT_FALSE(st.capped);
      EXPECT_LE(max_link_violation(m, pos), solver::kRestoreTolerance);
    }
  }
}
