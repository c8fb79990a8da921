// Each formula of the velocity layer (SPEC §5) against hand-computed values: the per-element
// update hpcm::dynamics::velocity_update (shared by the CPU layer and the CUDA kernel),
// make_constants and DynamicsParams::response_scale. The arithmetic is written next to
// every expected value. Positions are chosen as short binary fractions so that X+ - X- is
// exact in float; expected values carry only the rounding of the final products.
#include <gtest/gtest.h>

#include <random>

#include "dynamics/velocity_update.hpp"
#include "hpcm/param_table.hpp"
#include "hpcm/params.hpp"

using namespace hpcm;
using hpcm::dynamics::LayerConstants;
using hpcm::dynamics::make_constants;

namespace {

/// dynamics::velocity_update in absolute coordinates: it works on displacements u = X - X0 from
/// the element's rest position X0 (`rest`); these tests state positions, so they go through u.
Vec3 update_abs(const LayerConstants& k, int tissue, bool fixed, Vec3 pre, Vec3 post, Vec3 rest, Vec3& v,
                float* speed = nullptr) {
  return rest + dynamics::velocity_update(k, tissue, fixed, pre - rest, post - rest, rest, v, speed);
}

constexpr int kAir = 0, kSkin = 1, kMuscle = 2, kBone = 3;
constexpr float kTol = 1e-6f;
const Int3 kDims{10, 12, 8};

#define EXPECT_VEC_NEAR(a, bx, by, bz)   \
  do {                                   \
    const Vec3 a_ = (a);                 \
    EXPECT_NEAR(a_.x, (bx), kTol) << #a; \
    EXPECT_NEAR(a_.y, (by), kTol) << #a; \
    EXPECT_NEAR(a_.z, (bz), kTol) << #a; \
  } while (0)

DynamicsParams simple_params(float alpha) {
  DynamicsParams p;
  p.mode = DampingMode::Simple;
  p.alpha = alpha;
  p.inverse_mass = {1.0f, 1.0f, 0.15f, 0.0f};  // SPEC §5.3 defaults: s = {1, 1, 0.15, 0}
  p.dead_zone = 1e-3f;
  p.v_max = 0.5f;
  p.beta = 1.0f;
  p.rho = {1.0f, 1.0f, 1.0f, 1.0f};
  p.margin = 2.0f;
  return p;
}

DynamicsParams visco_params() {
  DynamicsParams p = simple_params(0.85f);
  p.mode = DampingMode::Viscoelastic;
  p.b0 = 0.15f;
  p.b1 = {0.0f, 0.5f, 0.5f, 0.5f};  // SPEC §5.4 defaults, b1 = 0 for air
  return p;
}

/// Every dynamics key of `d` within its range (the parameter table's checks; the rules that
/// relate several sections are not what these tests are about).
void check_ranges(const DynamicsParams& d) {
  Params all;
  all.dynamics = d;
  check_param_ranges(all);
}

LayerConstants K(const DynamicsParams& p) {
  check_ranges(p);
  return make_constants(p, kDims);
}

}  // namespace

// ---------------------------------------------------------------- §5.3 response scale

TEST(ResponseScale, SpecDefaultsNormaliseByLargest) {
  DynamicsParams p;
  p.inverse_mass = {1.0f, 1.0f, 0.15f, 0.0f};
  const PerTissue s = p.response_scale();  // max = 1: s = m^-1 / 1
  EXPECT_FLOAT_EQ(s[kAir], 1.0f);
  EXPECT_FLOAT_EQ(s[kSkin], 1.0f);
  EXPECT_FLOAT_EQ(s[kMuscle], 0.15f);
  EXPECT_FLOAT_EQ(s[kBone], 0.0f);
}

TEST(ResponseScale, NormalisesWhenLargestIsNotOne) {
  DynamicsParams p;
  p.inverse_mass = {2.0f, 4.0f, 1.0f, 0.0f};  // max = 4: {2/4, 4/4, 1/4, 0/4}
  const PerTissue s = p.response_scale();
  EXPECT_FLOAT_EQ(s[kAir], 0.5f);
  EXPECT_FLOAT_EQ(s[kSkin], 1.0f);
  EXPECT_FLOAT_EQ(s[kMuscle], 0.25f);
  EXPECT_FLOAT_EQ(s[kBone], 0.0f);
}

TEST(ResponseScale, ClampedIntoSminSmax) {
  DynamicsParams p;
  p.inverse_mass = {2.0f, 4.0f, 1.0f, 0.0f};  // normalised {0.5, 1, 0.25, 0}
  p.s_min = 0.3f;
  p.s_max = 0.8f;
  check_ranges(p);
  const PerTissue s = p.response_scale();  // clamp into [0.3, 0.8]: {0.5, 0.8, 0.3, 0.3}
  EXPECT_FLOAT_EQ(s[kAir], 0.5f);
  EXPECT_FLOAT_EQ(s[kSkin], 0.8f);
  EXPECT_FLOAT_EQ(s[kMuscle], 0.3f);
  EXPECT_FLOAT_EQ(s[kBone], 0.3f);
}

TEST(MakeConstants, CopiesParametersAndBoundaryBox) {
  DynamicsParams p = visco_params();
  p.inverse_mass = {2.0f, 4.0f, 1.0f, 0.0f};
  p.rho = {1.0f, 1.5f, 0.5f, 2.0f};
  const LayerConstants k = K(p);
  EXPECT_EQ(k.mode, 2);
  EXPECT_FLOAT_EQ(k.b0, 0.15f);
  EXPECT_FLOAT_EQ(k.dead_zone, 1e-3f);
  EXPECT_FLOAT_EQ(k.v_max, 0.5f);
  EXPECT_FLOAT_EQ(k.beta, 1.0f);
  const PerTissue s = p.response_scale();
  for (int t = 0; t < kTissueCount; ++t) {
    EXPECT_EQ(k.s[t], s[t]);
    EXPECT_EQ(k.b1[t], p.b1[t]);
    EXPECT_EQ(k.rho[t], p.rho[t]);
    EXPECT_EQ(k.inv_mass[t], p.inverse_mass[t]);
  }
  // Box [-m, N-1+m] with m = 2 on dims (10, 12, 8): [-2, 11] x [-2, 13] x [-2, 9].
  EXPECT_FLOAT_EQ(k.lo[0], -2.0f);
  EXPECT_FLOAT_EQ(k.lo[1], -2.0f);
  EXPECT_FLOAT_EQ(k.lo[2], -2.0f);
  EXPECT_FLOAT_EQ(k.hi[0], 11.0f);
  EXPECT_FLOAT_EQ(k.hi[1], 13.0f);
  EXPECT_FLOAT_EQ(k.hi[2], 9.0f);
  p.mode = DampingMode::None;
  EXPECT_EQ(K(p).mode, 0);
  p.mode = DampingMode::Simple;
  EXPECT_EQ(K(p).mode, 1);
}

// ---------------------------------------------------------------- §5.2 dead zone

TEST(DeadZone, JustBelowEpsilonIsDropped) {
  const LayerConstants k = K(simple_params(0.85f));
  // dX = 0.999e-3 * (0.6, 0.8, 0): |dX| = 0.999e-3 < eps = 1e-3, so dX counts as 0.
  const Vec3 pre{0, 0, 0}, post{0.6f * 0.999e-3f, 0.8f * 0.999e-3f, 0};
  Vec3 v{0.1f, 0, 0};
  const Vec3 x = update_abs(k, kSkin, false, pre, post, pre, v);
  // V = 0.85 * 0.1 + 1 * 0 = 0.085 (the old velocity still decays)
  EXPECT_VEC_NEAR(v, 0.085f, 0.0f, 0.0f);
  // X = X+ + V: the ChainMail correction itself is kept, only the velocity ignores it.
  EXPECT_VEC_NEAR(x, post.x + 0.085f, post.y, 0.0f);

  Vec3 still{0, 0, 0};  // at rest: nothing at all happens
  const Vec3 x0 = update_abs(k, kSkin, false, pre, post, pre, still);
  EXPECT_EQ(still, (Vec3{0, 0, 0}));
  EXPECT_EQ(x0, post);
}

TEST(DeadZone, JustAboveEpsilonDrivesVelocity) {
  const LayerConstants k = K(simple_params(0.85f));
  // dX = 1.001e-3 * (0.6, 0.8, 0) = (6.006e-4, 8.008e-4, 0): |dX| = 1.001e-3 >= eps.
  const Vec3 pre{0, 0, 0}, post{0.6f * 1.001e-3f, 0.8f * 1.001e-3f, 0};
  Vec3 v{0.1f, 0, 0};
  const Vec3 x = update_abs(k, kSkin, false, pre, post, pre, v);
  // V = 0.85 * (0.1, 0, 0) + 1 * (6.006e-4, 8.008e-4, 0) = (0.0856006, 0.0008008, 0)
  EXPECT_VEC_NEAR(v, 0.0856006f, 0.0008008f, 0.0f);
  EXPECT_VEC_NEAR(x, 0.0006006f + 0.0856006f, 0.0008008f + 0.0008008f, 0.0f);
}

TEST(DeadZone, ZeroDisablesIt) {
  DynamicsParams p = simple_params(0.0f);
  p.dead_zone = 0.0f;
  const LayerConstants k = K(p);
  const Vec3 pre{0, 0, 0}, post{1e-6f, 0, 0};
  Vec3 v{0, 0, 0};
  update_abs(k, kSkin, false, pre, post, pre, v);
  EXPECT_FLOAT_EQ(v.x, 1e-6f);  // V = 0 * 0 + 1 * 1e-6
}

// ---------------------------------------------------------------- §5.4 simple (B)

TEST(SimpleMode, AlphaUpdateSkinAndMuscle) {
  const LayerConstants k = K(simple_params(0.85f));
  const Vec3 pre{1, 2, 3}, post{1.25f, 1.875f, 3.0625f};  // dX = (0.25, -0.125, 0.0625) exactly
  const Vec3 v0{0.1f, -0.2f, 0.05f};
  Vec3 v = v0;
  Vec3 x = update_abs(k, kSkin, false, pre, post, pre, v);
  // skin, s = 1: V = 0.85*(0.1, -0.2, 0.05) + (0.25, -0.125, 0.0625)
  //               = (0.085 + 0.25, -0.17 - 0.125, 0.0425 + 0.0625) = (0.335, -0.295, 0.105)
  // |V| = sqrt(0.112225 + 0.087025 + 0.011025) = 0.4586 < v_max: no clamp
  EXPECT_VEC_NEAR(v, 0.335f, -0.295f, 0.105f);
  // X = X+ + 1*1*V = (1.585, 1.58, 3.1675)
  EXPECT_VEC_NEAR(x, 1.585f, 1.58f, 3.1675f);

  v = v0;
  x = update_abs(k, kMuscle, false, pre, post, pre, v);
  // muscle, s = 0.15: V = (0.085 + 0.0375, -0.17 - 0.01875, 0.0425 + 0.009375)
  //                     = (0.1225, -0.18875, 0.051875)
  EXPECT_VEC_NEAR(v, 0.1225f, -0.18875f, 0.051875f);
  EXPECT_VEC_NEAR(x, 1.25f + 0.1225f, 1.875f - 0.18875f, 3.0625f + 0.051875f);
}

TEST(SimpleMode, AlphaBounds) {
  const Vec3 pre{1, 2, 3}, post{1.25f, 1.875f, 3.0625f};
  Vec3 v{0.1f, -0.2f, 0.05f};
  update_abs(K(simple_params(0.0f)), kSkin, false, pre, post, pre, v);
  EXPECT_VEC_NEAR(v, 0.25f, -0.125f, 0.0625f);  // alpha 0: V = s*dX, no memory
  v = {0.1f, -0.2f, 0.05f};
  update_abs(K(simple_params(1.0f)), kSkin, false, pre, post, pre, v);
  EXPECT_VEC_NEAR(v, 0.35f, -0.325f, 0.1125f);  // alpha 1: V = V + s*dX, no damping
}

// ---------------------------------------------------------------- §5.4 viscoelastic (C)

TEST(ViscoelasticMode, DivisionUsesFrameStartDisplacement) {
  const LayerConstants k = K(visco_params());
  const Vec3 rest{1, 2, 3};
  const Vec3 pre{4, 6, 3};                          // X- - X0 = (3, 4, 0): |.| = 5
  const Vec3 post{4.25f, 5.875f, 3.0625f};          // dX = (0.25, -0.125, 0.0625)
  const Vec3 v0{0.1f, -0.2f, 0.05f};
  Vec3 v = v0;
  Vec3 x = update_abs(k, kSkin, false, pre, post, rest, v);
  // V~ = (0.1 + 0.25, -0.2 - 0.125, 0.05 + 0.0625) = (0.35, -0.325, 0.1125)
  // skin: denominator 1 + b0 + b1*|X- - X0| = 1 + 0.15 + 0.5*5 = 3.65
  // V = V~ / 3.65 = (0.0958904, -0.0890411, 0.0308219)
  EXPECT_VEC_NEAR(v, 0.35f / 3.65f, -0.325f / 3.65f, 0.1125f / 3.65f);
  EXPECT_VEC_NEAR(x, 4.25f + 0.35f / 3.65f, 5.875f - 0.325f / 3.65f, 3.0625f + 0.1125f / 3.65f);

  // The displacement term reads X- (frame start), not X+: with X- at rest the denominator
  // is 1 + 0.15 + 0.5*0 = 1.15 however far X+ lies from rest.
  v = v0;
  const Vec3 post2{1.25f, 1.875f, 3.0625f};  // dX = (0.25, -0.125, 0.0625) again
  update_abs(k, kSkin, false, rest, post2, rest, v);
  EXPECT_VEC_NEAR(v, 0.35f / 1.15f, -0.325f / 1.15f, 0.1125f / 1.15f);
}

TEST(ViscoelasticMode, AirHasNoDisplacementTerm) {
  const LayerConstants k = K(visco_params());
  ASSERT_EQ(k.b1[kAir], 0.0f);
  const Vec3 rest{1, 2, 3};
  const Vec3 dx{0.25f, -0.125f, 0.0625f};
  // Air (b1 = 0): denominator 1 + 0.15 + 0*|X- - X0| = 1.15 for any displacement:
  // V = (0.35, -0.325, 0.1125) / 1.15 = (0.304348, -0.282609, 0.0978261), |V| = 0.426 < v_max.
  for (const Vec3 off : {Vec3{0, 0, 0}, Vec3{3, 4, 0}, Vec3{-1, 0.5f, 2}}) {
    Vec3 v{0.1f, -0.2f, 0.05f};
    const Vec3 pre = rest + off;
    update_abs(k, kAir, false, pre, pre + dx, rest, v);
    EXPECT_VEC_NEAR(v, 0.35f / 1.15f, -0.325f / 1.15f, 0.1125f / 1.15f);
  }
}

TEST(ViscoelasticMode, NeverFlipsSignNeverGrows) {
  DynamicsParams p = visco_params();
  p.v_max = 10.0f;  // no magnitude clamp: the damper alone
  p.dead_zone = 0.0f;
  const LayerConstants k = K(p);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int n = 0; n < 20000; ++n) {
    const int t = n % 3;  // air, skin, muscle
    const Vec3 rest{4, 5, 4};
    const Vec3 pre = rest + Vec3{3 * u(rng), 3 * u(rng), 3 * u(rng)};
    const Vec3 post = pre + Vec3{u(rng), u(rng), u(rng)};
    Vec3 v{2 * u(rng), 2 * u(rng), 2 * u(rng)};
    const float s = k.s[t];
    const Vec3 vt{v.x + s * (post.x - pre.x), v.y + s * (post.y - pre.y), v.z + s * (post.z - pre.z)};
    update_abs(k, t, false, pre, post, rest, v);
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(v[a] * vt[a], 0.0f) << "sign flipped, sample " << n;
      EXPECT_LE(std::fabs(v[a]), std::fabs(vt[a])) << "grew, sample " << n;
    }
  }
}

// ---------------------------------------------------------------- §5.5 magnitude clamp

TEST(VelocityClamp, ScalesToVmaxKeepingDirection) {
  const LayerConstants k = K(simple_params(0.0f));  // V = s*dX, v_max = 0.5
  const Vec3 pre{0, 0, 0};
  Vec3 v{};
  // dX = (0.6, 0.8, 0), |dX| = 1 > 0.5: V = 0.5 * (0.6, 0.8, 0) = (0.3, 0.4, 0)
  Vec3 x = update_abs(k, kSkin, false, pre, Vec3{0.6f, 0.8f, 0}, pre, v);
  EXPECT_VEC_NEAR(v, 0.3f, 0.4f, 0.0f);
  EXPECT_VEC_NEAR(x, 0.9f, 1.2f, 0.0f);

  // dX = (-1.2, 0.5, -0.9), |dX| = sqrt(1.44 + 0.25 + 0.81) = sqrt(2.5) = 1.5811388:
  // V = dX * 0.5 / 1.5811388 = (-0.3794733, 0.1581139, -0.2846050)
  v = {};
  const Vec3 dx{-1.2f, 0.5f, -0.9f};
  update_abs(k, kSkin, false, pre, dx, pre, v);
  EXPECT_VEC_NEAR(v, -0.3794733f, 0.1581139f, -0.2846050f);
  EXPECT_NEAR(norm(v), 0.5f, kTol);
  // Same direction: V x dX = 0 and V . dX > 0.
  EXPECT_NEAR(v.y * dx.z - v.z * dx.y, 0.0f, kTol);
  EXPECT_NEAR(v.z * dx.x - v.x * dx.z, 0.0f, kTol);
  EXPECT_NEAR(v.x * dx.y - v.y * dx.x, 0.0f, kTol);
  EXPECT_GT(dot(v, dx), 0.0f);

  // Below v_max nothing changes: |(0.29, 0.4, 0)| = 0.494 < 0.5.
  v = {};
  update_abs(k, kSkin, false, pre, Vec3{0.29f, 0.4f, 0}, pre, v);
  EXPECT_EQ(v, (Vec3{0.29f, 0.4f, 0}));
}

TEST(VelocityClamp, AppliesAfterViscoelasticDivision) {
  DynamicsParams p = visco_params();
  const LayerConstants k = K(p);
  const Vec3 rest{0, 0, 0};
  Vec3 v{0.9f, 0, 0};
  // V~ = (0.9 + 0.25, 0, 0) = (1.15, 0, 0); air denominator 1.15 -> V = (1, 0, 0); clamp -> 0.5
  update_abs(k, kAir, false, rest, Vec3{0.25f, 0, 0}, rest, v);
  EXPECT_VEC_NEAR(v, 0.5f, 0.0f, 0.0f);
}

// ---------------------------------------------------------------- §5.1 bone / FIXED / none

TEST(NoDynamics, BoneWithZeroInverseMassStaysStill) {
  for (DynamicsParams p : {simple_params(0.85f), visco_params()}) {
    p.s_min = 0.3f;  // even with a non-zero response scale for bone, inverse mass 0 rules
    const LayerConstants k = K(p);
    ASSERT_EQ(k.inv_mass[kBone], 0.0f);
    Vec3 v{0.3f, 0.1f, 0};
    const Vec3 pre{1, 2, 3}, post{1.25f, 1.875f, 3.0625f};
    const Vec3 x = update_abs(k, kBone, false, pre, post, pre, v);
    EXPECT_EQ(v, (Vec3{0, 0, 0}));
    EXPECT_EQ(x, post);  // X = X+ exactly
  }
}

TEST(NoDynamics, BoneWithSmallInverseMassMoves) {
  DynamicsParams p = simple_params(0.85f);
  p.inverse_mass = {1.0f, 1.0f, 0.15f, 0.01f};  // s_bone = 0.01
  const LayerConstants k = K(p);
  Vec3 v{0.1f, 0, 0};
  update_abs(k, kBone, false, Vec3{1, 2, 3}, Vec3{1.25f, 2, 3}, Vec3{1, 2, 3}, v);
  EXPECT_VEC_NEAR(v, 0.085f + 0.0025f, 0.0f, 0.0f);  // 0.85*0.1 + 0.01*0.25
}

TEST(NoDynamics, FixedElementStaysStill) {
  for (DynamicsParams p : {simple_params(0.85f), visco_params()}) {
    const LayerConstants k = K(p);
    Vec3 v{0.3f, 0.1f, 0};
    const Vec3 pre{1, 2, 3}, post{1.25f, 1.875f, 3.0625f};
    const Vec3 x = update_abs(k, kSkin, true, pre, post, pre, v);
    EXPECT_EQ(v, (Vec3{0, 0, 0}));
    EXPECT_EQ(x, post);
  }
}

TEST(NoDynamics, ConditionAIsPlainChainMail) {
  DynamicsParams p = simple_params(0.85f);
  p.mode = DampingMode::None;
  const LayerConstants k = K(p);
  Vec3 v{0.3f, 0.1f, 0};
  const Vec3 pre{1, 2, 3}, post{1.25f, 1.875f, 3.0625f};
  const Vec3 x = update_abs(k, kSkin, false, pre, post, pre, v);
  EXPECT_EQ(v, (Vec3{0, 0, 0}));
  EXPECT_EQ(x, post);
}

// ---------------------------------------------------------------- §5.6 position update

TEST(PositionUpdate, BetaTimesRho) {
  DynamicsParams p = simple_params(0.0f);
  p.beta = 0.5f;
  p.rho = {1.0f, 1.5f, 0.5f, 1.0f};
  const LayerConstants k = K(p);
  const Vec3 pre{1, 2, 3}, post{1.25f, 1.875f, 3.0625f};  // dX = (0.25, -0.125, 0.0625)
  Vec3 v{};
  Vec3 x = update_abs(k, kSkin, false, pre, post, pre, v);
  // V = dX; gain = beta*rho_skin = 0.5*1.5 = 0.75: X = X+ + 0.75*dX
  //   = (1.25 + 0.1875, 1.875 - 0.09375, 3.0625 + 0.046875) = (1.4375, 1.78125, 3.109375)
  EXPECT_VEC_NEAR(v, 0.25f, -0.125f, 0.0625f);
  EXPECT_VEC_NEAR(x, 1.4375f, 1.78125f, 3.109375f);

  v = {};
  x = update_abs(k, kMuscle, false, pre, post, pre, v);
  // muscle: V = 0.15*dX = (0.0375, -0.01875, 0.009375); gain 0.5*0.5 = 0.25
  //   X = (1.25 + 0.009375, 1.875 - 0.0046875, 3.0625 + 0.00234375)
  EXPECT_VEC_NEAR(v, 0.0375f, -0.01875f, 0.009375f);
  EXPECT_VEC_NEAR(x, 1.259375f, 1.8703125f, 3.06484375f);

  p.beta = 0.0f;  // beta 0: the velocity is kept but does not move the element
  v = {};
  x = update_abs(K(p), kSkin, false, pre, post, pre, v);
  EXPECT_VEC_NEAR(v, 0.25f, -0.125f, 0.0625f);
  EXPECT_EQ(x, post);
}

// ---------------------------------------------------------------- §5.7 boundary clamp

TEST(BoundaryClamp, PositionsClampedVelocityKept) {
  DynamicsParams p = simple_params(0.0f);
  p.v_max = 10.0f;
  const LayerConstants k = K(p);  // box [-2, 11] x [-2, 13] x [-2, 9]
  const Vec3 pre{10.5f, -1.5f, 4.0f}, post{10.875f, -1.875f, 4.25f};  // dX = (0.375, -0.375, 0.25)
  Vec3 v{};
  const Vec3 x = update_abs(k, kSkin, false, pre, post, pre, v);
  // X = X+ + dX = (11.25, -2.25, 4.5) -> clamped to (11, -2, 4.5); V itself is not changed.
  EXPECT_VEC_NEAR(v, 0.375f, -0.375f, 0.25f);
  EXPECT_EQ(x, (Vec3{11.0f, -2.0f, 4.5f}));

  // The clamp applies to every element, also those without dynamics.
  Vec3 vb{};
  EXPECT_EQ(update_abs(k, kBone, false, post, Vec3{12.5f, 14.0f, -3.0f}, post, vb), (Vec3{11.0f, 13.0f, -2.0f}));

  p.margin = 0.0f;  // margin 0: box [0, N-1]
  Vec3 v0{};
  EXPECT_EQ(update_abs(K(p), kSkin, false, pre, post, pre, v0), (Vec3{9.0f, 0.0f, 4.5f}));
}

// On displacements the wall is the element's own interval [-m - X0, N - 1 + m - X0]: an element
// at lattice x = 1000 of a 1024-cell axis may move 25 cells (margin 2) toward +x, not more, and
// the bound is exact (no float step of the coordinate 1000 in it).
TEST(BoundaryClamp, OnDisplacementsTheBoundsAreTheElementsOwn) {
  DynamicsParams p = simple_params(0.0f);
  p.margin = 2.0f;
  const LayerConstants k = make_constants(p, Int3{1024, 48, 32});
  const Vec3 rest{1000.0f, 3.0f, 0.0f};
  Vec3 v{};
  // u+ = (30, -7, 0.25): beyond the +x wall and below the -y wall.
  const Vec3 u = dynamics::velocity_update(k, kBone, false, Vec3{}, Vec3{30.0f, -7.0f, 0.25f}, rest, v);
  EXPECT_EQ(u, (Vec3{25.0f, -5.0f, 0.25f}));
  // Within the wall nothing is clamped, to the bit: a displacement of a float step at 1e-6.
  const Vec3 small{1e-6f, -3e-7f, 2e-7f};
  EXPECT_EQ(dynamics::velocity_update(k, kBone, false, small, small, rest, v), small);
}
