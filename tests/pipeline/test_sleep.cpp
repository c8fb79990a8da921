// Sleeping bricks (solver.sleep, dynamics.sleep_speed): the paper protocol with sleeping and
// with every brick kept awake (the exact reference) stays within 1e-3 lattice units per element
// on every frame under A, B and C (measured: at most 5e-6), sleeping really stops the work once the tissue is
// still, and the behaviour checks hold with every brick awake too.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include <algorithm>
#include <cstdio>

#include "hpcm/experiment.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/scenario.hpp"
#include "hpcm/simulation.hpp"

using namespace hpcm;

namespace {

Model phantom(Int3 dims, const Params& p) {
  PhantomOptions o;
  o.dims = dims;
  return build_model(make_phantom(o), p);
}

float max_diff(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  float d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, norm(a[i] - b[i]));
  return d;
}

}  // namespace

TEST(Sleep, WithinOneThousandthOfTheAwakeReferenceAndComesToRest) {
  const Params base;
  ASSERT_TRUE(base.solver.sleep);
  const Model m = phantom({48, 48, 32}, base);
  // B (alpha 0.98) moves, and its links are restored, in every frame up to about frame 600, then
  // takes about 800 frames more to fall below sleep_speed (measured: idle from frame ~1400).
  constexpr int kSettle = 1400;
  // The bound on |x_sleep - x_awake|: 1e-3 (measured 0 under A, 4.6e-6 under B, 2.8e-6 under C;
  // SPEC §4 allows 1e-2). A velocity zeroed by sleeping (at most 1e-7 / (1 - alpha) = 5e-6 of
  // position) can tip a relaxation-threshold decision, which moves an element by the threshold
  // (0.03): before the relaxation slack it did under B (0.036; docs/solver.md, "Sleeping").
  auto bound = [](DampingMode) { return 1e-3f; };
  for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic}) {
    Params asleep = base, awake = base;
    asleep.dynamics.mode = awake.dynamics.mode = mode;
    awake.solver.sleep = false;
    Simulation a(m, asleep), b(m, awake);
    ScenarioPlayer pa(Scenario::paper_protocol(), a), pb(Scenario::paper_protocol(), b);
    const int frames = Scenario::paper_protocol().frames + kSettle;
    float worst = 0;
    int idle_frames = 0;
    Index awake_min = b.model().size();
    for (int f = 0; f < frames; ++f) {
      const FrameReport ra = pa.done() ? a.step() : pa.step();
      const FrameReport rb = pb.done() ? b.step() : pb.step();
      worst = std::max(worst, max_diff(a.state().disp, b.state().disp));
      if (ra.active_bricks == 0) ++idle_frames;
      awake_min = std::min(awake_min, rb.active_elements);
    }
    std::printf("%s: max |x_sleep - x_awake| = %.3g over %d frames; %d idle frames with sleeping\n",
                damping_mode_name(mode), worst, frames, idle_frames);
    EXPECT_LE(worst, bound(mode)) << damping_mode_name(mode);
    EXPECT_GT(idle_frames, 0) << damping_mode_name(mode) << ": the still lattice must fall asleep";
    EXPECT_EQ(awake_min, b.model().size()) << "solver.sleep = false keeps every element awake";
  }
}

// SPEC 8 (every check the experiment reports) also holds with every brick awake. The checks
// required here (8.5, 8.7) hold on every lattice, so the lattice is 32x32x24 (a third of the
// elements of 48x48x32; ExperimentIntegrity holds them on it with sleeping): below the 64 along
// the two longest axes that the motion checks are held on, which are reported not applicable
// (with the lattice as the reason), never failed.
TEST(Sleep, ChecksHoldWithEveryBrickAwake) {
  Params p;
  p.solver.sleep = false;
  const Model m = phantom({32, 32, 24}, p);
  ExperimentOptions opt;
  opt.settle_frames = 2000;
  const ExperimentResult r = run_experiment(m, p, opt);
  ASSERT_EQ(r.checks.size(), 33u) << "the paper protocol reports 33 checks";
  for (const Check& c : r.checks) {
    if (c.status == CheckStatus::NotApplicable) {
      EXPECT_EQ(c.reason, "lattice 32×32×24 below 64 along its two longest axes") << c.name;
      continue;
    }
    EXPECT_TRUE(c.holds()) << c.name << ": " << check_status_name(c.status) << ", value " << c.value << ", threshold "
                           << c.threshold;
  }
  EXPECT_GE(r.count(CheckStatus::Held), 15) << "the every-lattice checks (8.5, 8.7) are required";
}
