// The link restoration far from the lattice origin, where one float step of a coordinate (1.5e-5
// between 128 and 256, 3.1e-5 up to 512, 6.1e-5 beyond) is larger than the integrity check's
// 1e-5. On axes that reach 128 the restoration rounds every box limit toward the inside of the
// box, so every link it touches ends exactly inside its box (violation 0), at any distance from
// the origin; the tool limit reserves the float steps that rounding can take from a chain
// stretched to its slack. Below 128 it rounds to nearest (half a float step, at most 3.8e-6).
// Rounded to nearest (the version before), a restored link could stay half a float step outside:
// 1.52e-5 at y = 490 and 3.05e-5 at y = 588, beyond 1e-5 (docs/solver.md, "Float resolution").
#include <gtest/gtest.h>

#include <cmath>
#include <ostream>
#include <random>

#include "hpcm/simulation.hpp"
#include "hpcm/state.hpp"
#include "solver/link_restore.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;

namespace {

struct VectorAccess : solver::RestoreAccess {
  std::vector<Vec3>& pos;
  explicit VectorAccess(std::vector<Vec3>& p) : pos(p) {}
  Vec3 position(Index i) const override { return pos[static_cast<std::size_t>(i)]; }
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
// outside their boxes), then restored. Every link along the bar must end exactly inside its box.
TEST_P(RestoreRounding, ScatteredLinksEndExactlyInTheirBoxes) {
  const ScatterCase sc = GetParam();
  const Model m = build_model(test::make_volume({sc.length, 2, 2}, [](int x, int, int) { return x % 7 < 3 ? 50.0f : -100.0f; }),
                              Params{});
  solver::BrickGrid grid;
  grid.init(m.dims, 8);
  const solver::Wall wall = solver::make_wall(m.dims, 2.0f);
  // x (the bar's length, beyond 128) rounds inward: exactly in the box. y and z (coordinates up
  // to 3) round to nearest: within half a float step there (1.2e-7).
  ASSERT_TRUE(solver::rounds_inward(wall.hi[0]));
  float allowed = 0;
  for (int b = 1; b < (sc.all_axes ? 3 : 1); ++b) {
    ASSERT_FALSE(solver::rounds_inward(wall.hi[b]));
    allowed = std::max(allowed, 0.5f * solver::float_step_above(wall.hi[b]));
  }
  float worst = 0;
  for (unsigned seed = 1; seed <= 200; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> jitter(-0.3f, 0.3f);
    std::vector<Vec3> pos(static_cast<std::size_t>(m.size()));
    std::vector<Index> seeds;
    for (Index i = 0; i < m.size(); ++i) {
      pos[static_cast<std::size_t>(i)] = m.rest(i);
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
// tolerance (links within it are left as the propagation and relaxation placed them; those
// beyond it are restored exactly).
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
