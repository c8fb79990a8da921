// The tool limit: a pull the tissue cannot stretch to is limited to the feasible offset
// (Gibson's rule), flagged, and leaves every link in its box, under all three dynamics modes.
//
// The case: an anchored bone slab with two cells of fat on top and air above that; the top fat
// cell is grabbed and pulled 6 cells away from the bone. Only the two links between the grab
// and the bone stand between the tool and an anchor, so the tool can move exactly their
// stretch slack (max_stretch each), not 6 cells.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <omp.h>

#include <random>
#include <utility>
#include <vector>

#include "hpcm/phantom.hpp"
#include "hpcm/simulation.hpp"
#include "hpcm/state.hpp"
#include "solver/tool_limit.hpp"
#include "solver_test_util.hpp"

using namespace hpcm;

namespace {

constexpr int kBoneTop = 9;  // bone for y <= 9, fat at y = 10, 11, air above
const Int3 kDims{20, 32, 12};

Model fat_over_bone(const Params& p) {
  return build_model(test::make_volume(kDims,
                                       [](int, int y, int) {
                                         return y <= kBoneTop ? 1000.0f : y <= kBoneTop + 2 ? -100.0f : -1024.0f;
                                       }),
                     p);
}

// The stretch slack of the two links from the grabbed fat cell down to the bone.
float chain_slack(const Model& m, int x, int z) {
  float s = 0;
  for (int y = kBoneTop; y <= kBoneTop + 1; ++y) s += m.link(1, m.index(x, y, z)).max_stretch;
  return s;
}

class ToolLimit : public ::testing::TestWithParam<DampingMode> {};

TEST_P(ToolLimit, SixCellPullOverTwoCellsOfFatIsLimitedToTheirSlack) {
  Params p;
  p.dynamics.mode = GetParam();
  const Model m = fat_over_bone(p);
  ASSERT_EQ(static_cast<Tissue>(m.tissue[static_cast<std::size_t>(m.index(10, kBoneTop, 6))]), Tissue::Bone);
  ASSERT_EQ(static_cast<Tissue>(m.tissue[static_cast<std::size_t>(m.index(10, kBoneTop + 2, 6))]), Tissue::SkinFat);
  const float slack = chain_slack(m, 10, 6);
  std::printf("chain slack %.6f\n", slack);
  ASSERT_GT(slack, 0.0f);
  ASSERT_LT(slack, 1.0f) << "two fat links cannot stretch a whole cell";

  Simulation sim(m, p);
  sim.grab(m.index(10, kBoneTop + 2, 6), 0.5f);
  ASSERT_EQ(sim.grabbed().size(), 1u);
  EXPECT_NEAR(sim.tool_limit_hi().y, slack, 1e-5f);

  StepOptions opt;
  opt.link_violation = true;
  opt.cell_jacobian = true;
  int limited_frames = 0;
  for (int f = 1; f <= 20; ++f) {  // 6 cells over 20 frames, as in the paper protocol
    const float want = 0.3f * float(f);
    sim.move_tool(Vec3{0.0f, want, 0.0f});
    const FrameReport r = sim.step(opt);
    EXPECT_NEAR(r.requested_offset, want, 1e-5f) << "frame " << f;
    const bool should_limit = want > slack;
    EXPECT_EQ(r.tool_limited, should_limit) << "frame " << f;
    EXPECT_EQ(sim.tool_limited(), should_limit) << "frame " << f;
    limited_frames += r.tool_limited ? 1 : 0;
    // The achieved offset is the closest feasible one: all the slack there is, no more.
    EXPECT_NEAR(sim.tool_offset().y, std::min(want, slack), 1e-5f) << "frame " << f;
    EXPECT_EQ(sim.tool_offset().x, 0.0f);
    EXPECT_EQ(sim.tool_offset().z, 0.0f);
    EXPECT_LE(r.max_link_violation, 1e-5f) << "frame " << f;
    EXPECT_GT(r.min_cell_jacobian, 0.0f) << "frame " << f;
  }
  EXPECT_EQ(limited_frames, 20 - int(std::floor(slack / 0.3f)));
  sim.release();
  for (int f = 0; f < 60; ++f) {
    const FrameReport r = sim.step(opt);
    EXPECT_FALSE(r.tool_limited);
    EXPECT_LE(r.max_link_violation, 1e-5f) << "idle frame " << f;
    EXPECT_GT(r.min_cell_jacobian, 0.0f) << "idle frame " << f;
  }
  // Bone stays put (anchored), whatever the dynamics did to the fat.
  for (int x = 0; x < kDims.x; ++x)
    EXPECT_EQ(sim.state().disp[m.index(x, kBoneTop, 6)], Vec3{});
}

INSTANTIATE_TEST_SUITE_P(Modes, ToolLimit,
                         ::testing::Values(DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic),
                         [](const ::testing::TestParamInfo<DampingMode>& i) {
                           return std::string(i.param == DampingMode::None     ? "A_none"
                                              : i.param == DampingMode::Simple ? "B_simple"
                                                                                : "C_viscoelastic");
                         });

}  // namespace

// solver.grab_slip: a grab of radius 1.5 centred on the top fat cell (two fat cells over the
// anchored bone) takes the fat cells under it, which touch the bone. Held, they limit the tool
// to the slack of one fat-bone link; slipping, they leave the tool to the top cell's chain of two
// links, as a grab of radius 0.5 would. The centre always stays held.
TEST(ToolLimit, ElementsBoundToAnAnchorSlipFromTheGrab) {
  for (bool slip : {false, true}) {
    Params p;
    p.solver.grab_slip = slip;
    const Model m = fat_over_bone(p);
    Simulation sim(m, p);
    const Index centre = m.index(10, kBoneTop + 2, 6);
    sim.grab(centre, 1.5f);
    int bound = 0;
    bool has_centre = false;
    for (Index g : sim.grabbed()) {
      has_centre |= g == centre;
      bound += m.coords(g).y == kBoneTop + 1;  // fat touching the bone
    }
    EXPECT_TRUE(has_centre);
    if (slip) {
      EXPECT_EQ(bound, 0) << "fat touching the anchored bone must slip";
      // The centre's layer (9 cells within 1.5) and the 5 air cells above it stay.
      EXPECT_EQ(sim.grabbed().size(), 14u);
      EXPECT_NEAR(sim.tool_limit_hi().y, chain_slack(m, 10, 6), 1e-5f);
    } else {
      EXPECT_GT(bound, 0);
      EXPECT_NEAR(sim.tool_limit_hi().y, m.link(1, m.index(10, kBoneTop, 6)).max_stretch, 1e-5f)
          << "held, the bound fat limits the tool to its one link to the bone";
    }
    std::printf("grab_slip %d: %zu grabbed, tool limit %.6f\n", slip ? 1 : 0, sim.grabbed().size(),
                sim.tool_limit_hi().y);
  }
}

// A grab on the lattice's border with boundary margin 0: the wall allows no outward offset at
// all, but offset 0 (the grab held where it is) is allowed and is not reported as limited;
// an outward pull is limited to exactly 0, an inward one is free.
TEST(ToolLimit, GrabOnTheWallWithMarginZeroIsNotLimitedAtRest) {
  Params p;
  p.dynamics.margin = 0.0f;
  p.solver.anchors = AnchorMode::None;
  const Model m = build_model(test::make_volume({12, 12, 12}, [](int, int, int) { return -100.0f; }), p);
  Simulation sim(m, p);
  sim.grab(m.index(0, 6, 6), 0.5f);
  ASSERT_EQ(sim.grabbed().size(), 1u);
  EXPECT_EQ(sim.tool_limit_lo().x, 0.0f);
  EXPECT_FALSE(sim.tool_limited());
  EXPECT_FALSE(sim.step({}).tool_limited);
  sim.move_tool(Vec3{-0.5f, 0.0f, 0.0f});
  EXPECT_TRUE(sim.tool_limited());
  EXPECT_EQ(sim.tool_offset().x, 0.0f);
  sim.move_tool(Vec3{0.25f, 0.0f, 0.0f});
  EXPECT_FALSE(sim.tool_limited());
  EXPECT_EQ(sim.tool_offset().x, 0.25f);
}

// The six searches of the tool limit (three axes, two directions) run on the available threads:
// the limits must not depend on how many there are. A grab inside the phantom's soft tissue,
// so every search has work to do.
TEST(ToolLimitSearch, SameLimitsOnOneAndTwoThreads) {
  const Params p;
  PhantomOptions o;
  o.dims = {40, 40, 24};
  const Model m = build_model(make_phantom(o), p);
  auto limits = [&](int threads) {
    omp_set_num_threads(threads);
    Simulation sim(m, p);
    sim.grab(m.index(20, 8, 12), 2.0f);
    return std::pair<Vec3, Vec3>{sim.tool_limit_lo(), sim.tool_limit_hi()};
  };
  const int before = omp_get_max_threads();
  const auto one = limits(1), two = limits(2);
  omp_set_num_threads(before);
  for (int b = 0; b < 3; ++b) {
    EXPECT_EQ(one.first[b], two.first[b]) << "axis " << b;
    EXPECT_EQ(one.second[b], two.second[b]) << "axis " << b;
    EXPECT_LT(one.first[b], 0.0f);
    EXPECT_GT(one.second[b], 0.0f);
  }
}

// The grab's limit is searched lazily (solver::ToolLimitSearch): each offset is clamped after
// exploring only as far as it needs. Whatever offsets are asked for, in whatever order (small
// steps, jumps, both signs, every axis), the clamp must be exactly that of the full search.
TEST(ToolLimitSearch, LazyClampIsExactlyTheFullSearchsClamp) {
  const Params p;
  PhantomOptions o;
  o.dims = {40, 40, 24};
  const Model m = build_model(make_phantom(o), p);
  std::vector<Index> grabbed;
  std::vector<Vec3> origin;
  for (int z = 10; z <= 14; ++z)
    for (int y = 6; y <= 10; ++y)
      for (int x = 18; x <= 22; ++x)
        if ((x - 20) * (x - 20) + (y - 8) * (y - 8) + (z - 12) * (z - 12) <= 4) {
          grabbed.push_back(m.index(x, y, z));
          origin.push_back(Vec3{0.1f, -0.05f, 0.0f});  // held slightly off rest
        }
  std::vector<std::uint8_t> anchored(static_cast<std::size_t>(m.size()), 0);
  for (Index i = 0; i < m.size(); ++i) anchored[static_cast<std::size_t>(i)] = m.tissue[static_cast<std::size_t>(i)] == static_cast<std::uint8_t>(Tissue::Bone);
  for (Index g : grabbed) anchored[static_cast<std::size_t>(g)] = 0;
  const float margin = p.dynamics.margin;
  const solver::ToolLimit full = solver::tool_limit(m, grabbed, origin, anchored, margin);
  solver::ToolLimitSearch lazy(m, grabbed, origin, anchored, margin);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> step(-0.4f, 0.4f), near(-1.0f, 1.0f), jump(-30.0f, 30.0f);
  Vec3 offset{};
  int limited = 0;
  for (int k = 0; k < 400; ++k) {
    if (k % 50 == 0)
      offset = Vec3{jump(rng), jump(rng), jump(rng)};  // far beyond the limit, then back
    else if (k % 25 == 0)
      offset = Vec3{near(rng), near(rng), near(rng)};
    else
      offset = offset + Vec3{step(rng), step(rng), step(rng)};
    const Vec3 a = lazy.clamp(offset), b = full.clamp(offset);
    for (int ax = 0; ax < 3; ++ax) ASSERT_EQ(a[ax], b[ax]) << "offset " << k << ", axis " << ax;
    limited += full.contains(offset) ? 0 : 1;
  }
  std::printf("%d of 400 offsets limited\n", limited);
  EXPECT_GT(limited, 50) << "the offsets must reach beyond the limit";
  EXPECT_LT(limited, 400) << "and stay inside it too";
  // Slow pulls along each axis and side from rest to past the limit (as a user drags): every
  // search is extended step by step across its bound.
  for (int ax = 0; ax < 3; ++ax)
    for (const float sign : {1.0f, -1.0f}) {
      solver::ToolLimitSearch pull(m, grabbed, origin, anchored, margin);
      const float end = 1.2f * (sign > 0 ? full.hi[ax] : -full.lo[ax]) + 0.5f;
      for (float t = 0.0f; t <= end; t += 0.05f) {
        Vec3 o{};
        o[ax] = sign * t;
        const Vec3 a = pull.clamp(o), b = full.clamp(o);
        ASSERT_EQ(a[ax], b[ax]) << "axis " << ax << ", side " << sign << ", offset " << t;
      }
    }
  const solver::ToolLimit all = lazy.limit();
  for (int ax = 0; ax < 3; ++ax) {
    EXPECT_EQ(all.lo[ax], full.lo[ax]);
    EXPECT_EQ(all.hi[ax], full.hi[ax]);
  }
}

// Grabs held off rest (the grabbed elements' displacements differ), random tissue, random
// anchors and margins: the lower side may then raise the offset (lo > 0), and the upper side
// must be settled for the raised value. Lazy and full clamps must agree bit for bit.
TEST(ToolLimitSearch, LazyClampMatchesOnRandomLatticesAndGrabsHeldOffRest) {
  std::mt19937 rng(12345);
  int cases = 0, raised = 0;
  for (int t = 0; t < 120; ++t) {
    const Params p;
    const int kind = t % 3;
    const Int3 dims = kind == 0   ? Int3{int(rng() % 10) + 3, int(rng() % 10) + 3, int(rng() % 8) + 3}
                      : kind == 1 ? Int3{140, int(rng() % 4) + 2, int(rng() % 4) + 2}
                                  : Int3{int(rng() % 5) + 2, 300, 3};
    std::uniform_real_distribution<float> hu(-1100.0f, 1500.0f);
    std::vector<float> hv(static_cast<std::size_t>(dims.x) * dims.y * dims.z);
    for (float& h : hv) h = hu(rng);
    const Model m = build_model(
        test::make_volume(dims, [&](int x, int y, int z) { return hv[static_cast<std::size_t>(x + dims.x * (y + dims.y * z))]; }), p);
    const float margin = rng() % 3 == 0 ? 0.0f : std::uniform_real_distribution<float>(0.0f, 5.0f)(rng);
    std::vector<Index> grabbed;
    std::vector<Vec3> origin;
    std::vector<std::uint8_t> used(static_cast<std::size_t>(m.size()), 0);
    std::uniform_real_distribution<float> off(-0.7f, 0.7f);
    const int want_grabbed = static_cast<int>(rng() % 4) + 1;
    for (int k = 0; k < want_grabbed; ++k) {
      const Index i = static_cast<Index>(rng() % static_cast<unsigned>(m.size()));
      if (used[static_cast<std::size_t>(i)]) continue;
      used[static_cast<std::size_t>(i)] = 1;
      grabbed.push_back(i);
      origin.push_back(rng() % 2 ? Vec3{off(rng), off(rng), off(rng)} : Vec3{});
    }
    std::vector<std::uint8_t> anchored(static_cast<std::size_t>(m.size()), 0);
    const int anchor_mode = static_cast<int>(rng() % 3);
    for (Index i = 0; i < m.size(); ++i)
      if (!used[static_cast<std::size_t>(i)])
        anchored[static_cast<std::size_t>(i)] =
            anchor_mode == 0 ? 0 : anchor_mode == 1 ? m.tissue[static_cast<std::size_t>(i)] == static_cast<std::uint8_t>(Tissue::Bone) : rng() % 20 == 0;
    const solver::ToolLimit full = solver::tool_limit(m, grabbed, origin, anchored, margin);
    solver::ToolLimitSearch lazy(m, grabbed, origin, anchored, margin);
    std::uniform_real_distribution<float> step(-0.3f, 0.3f), jump(-8.0f, 8.0f);
    Vec3 o{};
    for (int k = 0; k < 100; ++k) {
      if (k % 37 == 0) o = Vec3{jump(rng), jump(rng), jump(rng)};
      else o = o + Vec3{step(rng), step(rng), step(rng)};
      if (k % 53 == 0) o = Vec3{};
      const Vec3 a = lazy.clamp(o), b = full.clamp(o);
      ++cases;
      for (int ax = 0; ax < 3; ++ax) {
        ASSERT_EQ(a[ax], b[ax]) << "lattice " << t << ", offset " << k << ", axis " << ax;
        raised += b[ax] > o[ax] && o[ax] < full.lo[ax] && full.lo[ax] > 0.0f ? 1 : 0;
      }
    }
    const solver::ToolLimit all = lazy.limit();
    for (int ax = 0; ax < 3; ++ax) {
      ASSERT_EQ(all.lo[ax], full.lo[ax]) << "lattice " << t;
      ASSERT_EQ(all.hi[ax], full.hi[ax]) << "lattice " << t;
    }
  }
  std::printf("%d clamps, %d raised to a positive lower limit\n", cases, raised);
  EXPECT_GT(raised, 0) << "the case of a lower limit above 0 must occur";
}
