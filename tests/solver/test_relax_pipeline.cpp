// Propagation + relaxation inside the frame pipeline (hpcm::Simulation, plain ChainMail):
// frame-end consistency, the stiff bar, elastic return to rest, and thread-count determinism.
#include <gtest/gtest.h>
#include <omp.h>

#include <cstdio>
#include <cstring>
#include <random>

#include "hpcm/phantom.hpp"
#include "hpcm/scenario.hpp"
#include "hpcm/simulation.hpp"
#include "solver/reference/dijkstra.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;

namespace {

float max_rest_distance(const Model& m, const State& s) {
  float d = 0;
  for (Index i = 0; i < m.size(); ++i) d = std::max(d, norm(s.disp[i]));
  return d;
}

Params chainmail_params(int relax_sweeps) {
  Params p;
  p.dynamics.mode = DampingMode::None;  // plain HP-ChainMail: the velocity layer does nothing
  p.solver.relax_sweeps = relax_sweeps;
  p.solver.anchors = AnchorMode::None;  // the bone bar below must be free to move
  return p;
}

// Every frame of a pull on a heterogeneous lattice (a small phantom: skin, fat, muscle,
// organs, spine) ends with every link inside its box. (On lattices of independent random HU
// per element, neighbouring boxes of bone-stiff and air-soft links often cannot all be met
// at once; the empty-intersection fallback then leaves violations, see docs/solver.md.)
TEST(Relaxation, FramesEndConsistent) {
  PhantomOptions o;
  o.dims = {36, 36, 16};
  const Model m = build_model(make_phantom(o), chainmail_params(8));
  Simulation sim(m, chainmail_params(8));
  const Index centre = paper_grab_centre(m);
  sim.grab(centre, 1.5f);
  StepOptions opt;
  opt.link_violation = true;
  for (int f = 1; f <= 12; ++f) {
    sim.move_tool(Vec3{0.0f, -0.25f * float(f), 0.1f * float(f)});
    const FrameReport r = sim.step(opt);
    EXPECT_TRUE(r.deform);
    EXPECT_TRUE(r.propagate_converged);
    ASSERT_GE(r.max_link_violation, 0.0f);
    EXPECT_LE(r.max_link_violation, 1e-5f) << "frame " << f;
    EXPECT_LE(max_link_violation(sim.model(), sim.state().disp), 1e-5f) << "frame " << f;
    for (Index g : sim.grabbed())
      EXPECT_EQ(sim.state().disp[g], sim.tool_offset()) << "grabbed element off its target";
  }
  sim.release();
  for (int f = 0; f < 10; ++f) {
    const FrameReport r = sim.step(opt);
    EXPECT_FALSE(r.deform);
    EXPECT_EQ(r.propagate_sweeps, 0) << "the idle stage must not propagate";
    EXPECT_LE(r.max_link_violation, 1e-5f) << "idle frame " << f;
  }
}

// The stiff bone bar, grabbed at one end and pulled over several frames with relaxation:
// every bar-internal link stays within the bar's (bone) limits after every frame.
TEST(Relaxation, StiffBarStaysWithinItsLimits) {
  const Model m = build_model(test::make_volume({24, 9, 9}, [](int x, int y, int z) {
                                return (y == 4 && z == 4 && x >= 3 && x <= 20) ? 1000.0f : 50.0f;
                              }),
                              chainmail_params(8));
  Simulation sim(m, chainmail_params(8));
  sim.grab(m.index(20, 4, 4), 0.5f);
  ASSERT_EQ(sim.grabbed().size(), 1u);
  for (int f = 1; f <= 10; ++f) {
    sim.move_tool(Vec3{0.15f * f, 0.08f * f, 0.0f});
    sim.step();
    const State& s = sim.state();
    float worst = 0;
    for (int x = 3; x < 20; ++x) worst = std::max(worst, reference::link_violation(m, m.index(x, 4, 4), 0, s.disp));
    EXPECT_LE(worst, 1e-5f) << "frame " << f;
    // Rigid: the far end of the bar follows the tool within 17 bar links of slack.
    const Vec3 far = s.disp[m.index(3, 4, 4)];
    EXPECT_NEAR(far.x, 0.15f * f, 17 * 0.005f + 1e-4f) << "frame " << f;
    EXPECT_NEAR(far.y, 0.08f * f, 17 * 0.005f + 1e-4f) << "frame " << f;
  }
}

// After release, elastic relaxation brings the lattice back to rest. Border anchors hold
// the lattice in place (a free lattice may drift as a whole). Corrections below
// solver.relax_threshold are skipped, which leaves a residual offset of a few tens of
// thresholds: with 1e-5 the lattice is back within 1e-3 (22 frames measured); with 1e-4 it
// settled about 4e-3 from rest; with the default 0.03 (a local response, SPEC §8.8) it settles
// 0.067 from rest (measured), a little over two thresholds, and then stops moving.
constexpr int kReturnFrames = 60;  // stated bound, documented in docs/solver.md
Model two_tissue_cube(const Params& p) {
  return build_model(test::make_volume({16, 16, 16}, [](int x, int, int) { return x < 8 ? 50.0f : -100.0f; }), p);
}
// A pull of 1 cell toward the anchored border 6 cells away: within what the soft tissue
// between them can compress (a 2-cell pull is not, and is limited to about 1.2 cells).
void pull_and_release(Simulation& sim) {
  sim.grab(sim.model().index(8, 8, 8), 1.5f);
  for (int f = 1; f <= 10; ++f) {
    sim.move_tool(Vec3{0.0f, -0.1f * f, 0.0f});
    ASSERT_FALSE(sim.tool_limited()) << "frame " << f;
    sim.step();
  }
  ASSERT_GT(max_rest_distance(sim.model(), sim.state()), 0.9f);
  sim.release();
}

TEST(Relaxation, ReturnsToRestAfterRelease) {
  Params p = chainmail_params(8);
  p.solver.anchors = AnchorMode::Border;
  p.solver.relax_threshold = 1e-5f;
  Simulation sim(two_tissue_cube(p), p);
  pull_and_release(sim);
  const Model& m = sim.model();
  int frames = 0;
  float d = max_rest_distance(m, sim.state());
  while (d >= 1e-3f && frames < kReturnFrames) {
    sim.step();
    ++frames;
    d = max_rest_distance(m, sim.state());
  }
  EXPECT_LT(d, 1e-3f) << "still " << d << " from rest after " << frames << " frames";
  std::printf("returned to rest (max |X - X0| < 1e-3) after %d frames\n", frames);
}

TEST(Relaxation, DefaultThresholdSettlesNearRestAndStops) {
  Params p = chainmail_params(8);
  p.solver.anchors = AnchorMode::Border;
  Simulation sim(two_tissue_cube(p), p);
  pull_and_release(sim);
  for (int f = 0; f < 200; ++f) sim.step();
  const Model& m = sim.model();
  const float d = max_rest_distance(m, sim.state());
  EXPECT_LT(d, 3.0f * p.solver.relax_threshold);
  const FrameReport r = sim.step();
  EXPECT_EQ(r.moved_elements, 0) << "the lattice must come to a stop";
  std::printf("default threshold: %g from rest after 200 frames\n", d);
}

// ChainMail's slack (solver.relax_slack, solver::relax_step_applies). A smooth bump of 2 cells
// in uniform fat: every correction is far below the threshold, so under the threshold-only rule
// (slack 1e6) nothing moves and the bump stays; with a slack every element farther from rest
// takes its corrections until the whole bump lies within the slack of rest, and then the
// relaxation stops. Links stay in their boxes throughout.
struct BumpResult {
  float peak;   ///< largest distance from rest when the relaxation stopped
  int calls;    ///< relax(8) calls until a call moved nothing
  float worst_link;
};
BumpResult relax_smooth_bump(float slack) {
  Params p = chainmail_params(8);
  p.solver.relax_slack = slack;
  const Model m = build_model(test::make_volume({48, 48, 48}, [](int, int, int) { return -100.0f; }), p);
  State s;
  s.disp.resize(static_cast<std::size_t>(m.size()));
  s.vel.assign(s.disp.size(), Vec3{});
  s.time.assign(s.disp.size(), solver::kInf);
  s.flags.assign(s.disp.size(), 0);
  for (int z = 0; z < 48; ++z)
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 48; ++x) {
        const float r2 = float((x - 24) * (x - 24) + (y - 24) * (y - 24) + (z - 24) * (z - 24));
        s.disp[m.index(x, y, z)] = Vec3{0.0f, -2.0f * std::exp(-r2 / (2.0f * 10.0f * 10.0f)), 0.0f};
      }
  EXPECT_LE(max_link_violation(m, s.disp), 1e-5f) << "the bump must start with its links in their boxes";
  auto backend = make_backend(BackendKind::Cpu);
  backend->load(m, p, s);
  BumpResult out{0.0f, 0, 0.0f};
  for (; out.calls < 500; ++out.calls) {
    const std::vector<Vec3> before = s.disp;
    backend->snapshot();
    backend->relax(8);
    backend->download(s);
    out.worst_link = std::max(out.worst_link, max_link_violation(m, s.disp));
    if (s.disp == before) break;
  }
  out.peak = max_rest_distance(m, s);
  return out;
}

TEST(Relaxation, SlackBoundsWhereTheRelaxationStops) {
  const BumpResult threshold_only = relax_smooth_bump(1e6f);
  EXPECT_EQ(threshold_only.calls, 0) << "corrections below the threshold must be skipped everywhere";
  EXPECT_FLOAT_EQ(threshold_only.peak, 2.0f);
  for (float slack : {1.0f, 0.5f}) {
    const BumpResult b = relax_smooth_bump(slack);
    std::printf("slack %g: stopped %g from rest after %d relaxations of 8 sweeps\n", slack, b.peak, b.calls);
    EXPECT_LT(b.calls, 500) << "slack " << slack << ": the relaxation must stop";
    EXPECT_LT(b.peak, slack) << "slack " << slack;
    EXPECT_GT(b.peak, 0.5f * slack) << "slack " << slack << ": within the slack, small corrections are skipped";
    EXPECT_LE(b.worst_link, 1e-5f) << "slack " << slack;
  }
}

// Bitwise identical results with 1 and with 2 threads, full pipeline (condition C).
TEST(Determinism, OneAndTwoThreadsBitwiseIdentical) {
  PhantomOptions o;
  o.dims = {40, 40, 20};
  Params p;  // defaults: viscoelastic damping, relaxation on
  const Model m = build_model(make_phantom(o), p);
  const Scenario sc = Scenario::paper_protocol(4.0f, 8, 3, 12);
  State out[2];
  const int threads[2] = {1, 2};
  const int saved = omp_get_max_threads();
  for (int k = 0; k < 2; ++k) {
    omp_set_num_threads(threads[k]);
    Simulation sim(m, p);
    ScenarioPlayer player(sc, sim);
    while (!player.done()) player.step();
    out[k] = sim.state();
  }
  omp_set_num_threads(saved);
  ASSERT_EQ(out[0].disp.size(), out[1].disp.size());
  const std::size_t n = out[0].disp.size();
  EXPECT_EQ(std::memcmp(out[0].disp.data(), out[1].disp.data(), n * sizeof(Vec3)), 0);
  EXPECT_EQ(std::memcmp(out[0].vel.data(), out[1].vel.data(), n * sizeof(Vec3)), 0);
  EXPECT_EQ(std::memcmp(out[0].time.data(), out[1].time.data(), n * sizeof(float)), 0);
  // The run did something: otherwise equality would be trivial.
  EXPECT_GT(max_rest_distance(m, out[0]), 0.01f);
}

}  // namespace
