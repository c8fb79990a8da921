// The link restoration far from the lattice origin, where one float step of a coordinate
// (1.5e-5 between 128 and 256) is larger than the integrity check's 1e-5. The restoration takes
// the midpoint of two consistent results; rounding that midpoint could leave a link a float step
// and a half outside its box (1.049e-5 was measured on the DICOM series at downsample 2; 8.2e-6
// with a last lower and raise pass from the midpoints). These two cases hold the restoration to
// half a float step; neither reproduced the midpoint's excess on its own (both hold without the
// last passes too), so they guard the bound, not the particular DICOM case.
#include <gtest/gtest.h>

#include <cmath>
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

}  // namespace

TEST(RestoreRounding, RestoredLinksWithinHalfAFloatStepBeyond128) {
  // A bar 200 x 2 x 2 of muscle and fat; elements with x in [130, 190) are scattered along x by up
  // to 0.3 cells (far outside their boxes), then restored. Measured: at most half a float step
  // (7.63e-6), with or without the last passes; scattered across x = 128 and on all three axes,
  // 1.01e-5 with or without them (docs/solver.md, "Float resolution": not a guarantee).
  const Model m = build_model(test::make_volume({200, 2, 2}, [](int x, int, int) { return x % 7 < 3 ? 50.0f : -100.0f; }), Params{});
  solver::BrickGrid grid;
  grid.init(m.dims, 8);
  const solver::Wall wall = solver::make_wall(m.dims, 2.0f);
  const float half_step = 0.5f * (std::nextafter(255.0f, 256.0f) - 255.0f);  // 7.63e-6
  float worst = 0;
  for (unsigned seed = 1; seed <= 400; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> jitter(-0.3f, 0.3f);
    std::vector<Vec3> pos(static_cast<std::size_t>(m.size()));
    std::vector<Index> seeds;
    for (Index i = 0; i < m.size(); ++i) {
      pos[static_cast<std::size_t>(i)] = m.rest(i);
      if (m.coords(i).x >= 130 && m.coords(i).x < 190) {
        pos[static_cast<std::size_t>(i)].x += jitter(rng);
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
    EXPECT_LE(v, half_step + 1e-7f) << "seed " << seed;
  }
  std::printf("largest link violation after restoration over 400 scatters: %.3g (half a float step %.3g)\n", worst,
              half_step);
}

// A pull at the tool limit beyond coordinate 128: fat between the tool (x = 140) and an anchored
// bone plate (x = 146) is stretched exactly to its slack, so the chain's links are at the edge of
// their boxes in both of the restoration's results, and rounding their midpoint pushed links
// past the limit. Every frame's ChainMail stage must leave every link within half a float step.
TEST(RestoreRounding, PullAtTheToolLimitBeyond128) {
  const Volume v = test::make_volume({152, 9, 9}, [](int x, int, int) { return x >= 146 ? 700.0f : -100.0f; });
  const float half_step = 0.5f * (std::nextafter(255.0f, 256.0f) - 255.0f);
  float worst = 0;
  for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic}) {
    Params p;
    p.dynamics.mode = mode;
    const Model m = build_model(v, p);
    Simulation sim(m, p);
    sim.grab(m.index(140, 4, 4), 1.5f);
    StepOptions opt;
    opt.link_violation = true;
    bool limited = false;
    for (int f = 1; f <= 40; ++f) {
      if (f <= 20) sim.move_tool(Vec3{0.15f * float(f), 0.05f * float(f), 0.0f});
      if (f == 31) sim.release();
      const FrameReport r = sim.step(opt);
      limited = limited || r.tool_limited;
      worst = std::max(worst, r.max_link_violation);
      EXPECT_LE(r.max_link_violation, half_step + 1e-7f) << "mode " << static_cast<int>(mode) << " frame " << f;
    }
    EXPECT_TRUE(limited) << "the pull must reach the tool limit";
  }
  std::printf("largest link violation after the ChainMail stage: %.3g\n", worst);
}
