// Tests of the sequential references themselves (Dijkstra-order rule, Gibson's ChainMail):
// they must be right before they can judge the parallel solver.
#include <gtest/gtest.h>

#include <random>

#include "hpcm/state.hpp"
#include "solver/reference/dijkstra.hpp"
#include "solver/reference/gibson.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;
using hpcm::reference::DijkstraPropagator;
using hpcm::reference::GibsonChainMail;
using hpcm::reference::kInf;

namespace {

std::vector<Vec3> rest_positions(const Model& m) { return State::rest(m).disp; }  // u = 0

// 1-D chain along x, rest spacing 1, tau 0.1 (stretch up to 0.1): pulling the last element by 0.8
// stretches the last 8 links by 0.1 each; elements further away do not move.
TEST(DijkstraReference, ChainStretchEachLinkAbsorbsTau) {
  const Model m = build_model(test::make_volume({12, 1, 1}, [](int, int, int) { return 0.0f; }),
                              test::uniform_params(0.1f, 0.3f));
  ASSERT_NEAR(m.link(0, 0).max_stretch, 0.1f, 1e-7f);
  ASSERT_NEAR(m.link(0, 0).min_stretch, -0.08f, 1e-7f);
  std::vector<Vec3> pos = rest_positions(m);
  DijkstraPropagator d(m);
  const Index reached = d.run(pos, {11}, {Vec3{0.8f, 0, 0}});
  for (int x = 0; x < 12; ++x) {
    const int k = 11 - x;  // links from the pulled end
    const float expect = std::max(0.0f, 0.8f - 0.1f * float(k));
    EXPECT_NEAR(pos[x].x, expect, 1e-5f) << "x=" << x;
    EXPECT_EQ(pos[x].y, 0.0f);
    EXPECT_EQ(pos[x].z, 0.0f);
  }
  // Elements 1 and more links beyond the stop (k >= 9) keep their bits and t = +inf.
  for (int x = 0; x <= 2; ++x) {
    EXPECT_EQ(pos[x].x, 0.0f);
    EXPECT_EQ(d.time()[x], kInf);
  }
  // Arrival times: k links of w = 0.3 each.
  for (int k = 1; k <= 7; ++k) EXPECT_NEAR(d.time()[11 - k], 0.3f * k, 1e-5f) << k;
  EXPECT_EQ(d.time()[11], 0.0f);
  EXPECT_GE(reached, 7);
  EXPECT_LE(reached, 8);
}

TEST(DijkstraReference, ChainCompressionUsesMinD) {
  const Model m = build_model(test::make_volume({12, 1, 1}, [](int, int, int) { return 0.0f; }),
                              test::uniform_params(0.1f, 0.3f));
  std::vector<Vec3> pos = rest_positions(m);
  DijkstraPropagator d(m);
  d.run(pos, {0}, {Vec3{0.4f, 0, 0}});  // push the first element toward +x: compression
  for (int x = 0; x < 12; ++x) {
    const float expect = std::max(0.0f, 0.4f - 0.08f * float(x));
    EXPECT_NEAR(pos[x].x, expect, 1e-5f) << "x=" << x;
  }
  for (int x = 6; x < 12; ++x) EXPECT_EQ(pos[x].x, 0.0f);
}

// A wave is a fixed point of the rule: re-evaluating the rule for every element from the
// final neighbour times and positions reproduces its time and position exactly.
TEST(DijkstraReference, WaveIsFixedPointOfTheRule) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> hu(-1000.0f, 1000.0f);
  const Model m = build_model(test::make_volume({14, 13, 12}, [&](int, int, int) { return hu(rng); }), Params{});
  std::vector<Vec3> p0 = rest_positions(m);
  const std::vector<Index> fixed = test::ball(m, {6, 6, 6}, 1.5f);
  std::vector<Vec3> targets;
  for (Index i : fixed) targets.push_back(Vec3{1.3f, -2.1f, 0.7f});
  std::vector<Vec3> pos = p0;
  DijkstraPropagator d(m);
  const Index reached = d.run(pos, fixed, targets);
  EXPECT_GT(reached, 50);
  std::vector<std::uint8_t> is_fixed(static_cast<std::size_t>(m.size()), 0);
  for (Index i : fixed) is_fixed[i] = 1;
  Index checked = 0;
  for (Index e = 0; e < m.size(); ++e) {
    if (is_fixed[e]) continue;
    const auto r = reference::evaluate_rule(m, e, p0, pos, d.time());
    ASSERT_EQ(r.time, d.time()[e]) << "element " << e;
    ASSERT_EQ(r.pos, pos[e]) << "element " << e;
    ++checked;
  }
  EXPECT_EQ(checked, m.size() - static_cast<Index>(fixed.size()));
}

// The fixed-point check is sharp: a single perturbed element is detected.
TEST(DijkstraReference, FixedPointCheckDetectsAPerturbation) {
  const Model m = build_model(test::make_volume({10, 10, 10}, [](int, int, int) { return 50.0f; }), Params{});
  std::vector<Vec3> p0 = rest_positions(m);
  std::vector<Vec3> pos = p0;
  DijkstraPropagator d(m);
  d.run(pos, {m.index(5, 5, 5)}, {Vec3{0, 0, 1.5f}});
  const Index e = m.index(5, 5, 7);
  ASSERT_LT(d.time()[e], kInf);
  pos[e].z += 1e-4f;
  const auto r = reference::evaluate_rule(m, m.index(5, 5, 8), p0, pos, d.time());
  EXPECT_FALSE(r.pos == pos[m.index(5, 5, 8)]);
}

// Reusing a propagator (lazy reset) gives the same wave as a fresh one.
TEST(DijkstraReference, ReusedPropagatorEqualsFresh) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> hu(-1000.0f, 1000.0f);
  const Model m = build_model(test::make_volume({12, 12, 12}, [&](int, int, int) { return hu(rng); }), Params{});
  DijkstraPropagator reused(m);
  for (int k = 0; k < 3; ++k) {
    const std::vector<Index> fixed{m.index(2 + 3 * k, 5, 6)};
    const std::vector<Vec3> tg{Vec3{0.5f * k + 0.5f, 1.0f, 0}};
    std::vector<Vec3> a = rest_positions(m), b = a;
    reused.run(a, fixed, tg);
    DijkstraPropagator fresh(m);
    fresh.run(b, fixed, tg);
    EXPECT_EQ(test::max_abs_diff(a, b), 0.0f);
    EXPECT_EQ(reused.time(), fresh.time());
  }
}

TEST(DijkstraReference, UpstreamViolationFindsABrokenLink) {
  const Model m = build_model(test::make_volume({4, 1, 1}, [](int, int, int) { return 0.0f; }),
                              test::uniform_params(0.1f, 0.3f));
  std::vector<Vec3> pos = rest_positions(m);
  std::vector<float> t{0.0f, 0.3f, kInf, kInf};
  EXPECT_EQ(reference::upstream_link_violation(m, pos, t), 0.0f);
  pos[1].x = 0.5f;  // link 0-1 stretched to 1.5 (max 1.1), link 1-2 compressed to 0.5 (min 0.92)
  EXPECT_NEAR(reference::upstream_link_violation(m, pos, t), 0.42f, 1e-5f);
  pos[1] = {0.0f, 0.3f, 0.0f};  // shear 0.3 > 0.1 on both links
  EXPECT_NEAR(reference::upstream_link_violation(m, pos, t), 0.2f, 1e-5f);
}

// Gibson's classic ChainMail, homogeneous lattice, one grabbed element pulled along each
// axis and obliquely: every link of the lattice ends inside its box.
TEST(GibsonReference, HomogeneousSinglePullSatisfiesAllBoxes) {
  const Model m = build_model(test::make_volume({15, 15, 15}, [](int, int, int) { return 50.0f; }), Params{});
  const Vec3 pulls[] = {{2, 0, 0}, {0, -2, 0}, {0, 0, 1.5f}, {1, 1, 0}, {0.7f, -0.9f, 1.2f}};
  GibsonChainMail g(m);
  for (const Vec3& d : pulls) {
    std::vector<Vec3> pos = rest_positions(m);
    const Index c = m.index(7, 7, 7);
    const Index moved = g.run(pos, {c}, {d});
    EXPECT_GT(moved, 10);
    EXPECT_EQ(pos[c], d);
    EXPECT_LE(max_link_violation(m, pos), 1e-5f) << d.x << "," << d.y << "," << d.z;
  }
}

TEST(GibsonReference, ChainMatchesDijkstra) {
  const Model m = build_model(test::make_volume({1, 12, 1}, [](int, int, int) { return 0.0f; }),
                              test::uniform_params(0.1f, 0.3f));
  const std::vector<Vec3> p0 = rest_positions(m);
  const auto g = reference::gibson_propagate(m, p0, {11}, {Vec3{0, 0.8f, 0}});
  std::vector<Vec3> d = p0;
  DijkstraPropagator(m).run(d, {11}, {Vec3{0, 0.8f, 0}});
  EXPECT_LE(test::max_abs_diff(g, d), 1e-6f);
  EXPECT_NEAR(g[3].y, 0.0f, 1e-5f);
  EXPECT_NEAR(g[4].y, 0.1f, 1e-5f);
}

}  // namespace
