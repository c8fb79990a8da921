// The link box, the clamp intervals and the wall on displacements from rest (u = X - X0) against
// the same rules on absolute positions X = X0 + u, where absolute floats are exact enough to
// compare (small lattice indices): the u-space rules are the absolute ones, moved by X0.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/link_box.hpp"
#include "solver/restore.hpp"
#include "solver/rules.hpp"

using namespace hpcm;

namespace {

/// The absolute box of a link (its + end minus its - end): spacing in [1 + min_stretch,
/// 1 + max_stretch] along the link, |d| <= shear across it; computed in double.
double absolute_violation(const Vec3& x_lo, const Vec3& x_hi, const LinkLimits& L, int a) {
  double v = 0;
  for (int b = 0; b < 3; ++b) {
    const double d = static_cast<double>(x_hi[b]) - x_lo[b];
    const double e = b == a ? std::max({0.0, (1.0 + L.min_stretch) - d, d - (1.0 + L.max_stretch)}) : std::max(0.0, std::fabs(d) - L.shear);
    v = std::max(v, e);
  }
  return v;
}

}  // namespace

TEST(LinkBoxDisplacements, ViolationMatchesTheAbsoluteBoxNearTheOrigin) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> tau(0.005f, 1.0f), u(-0.6f, 0.6f);
  std::uniform_int_distribution<int> at(0, 6);
  int outside = 0;
  for (int it = 0; it < 20000; ++it) {
    const LinkLimits L = limits_from_tau(tau(rng), 1.0f);
    const int a = it % 3;
    const Vec3 x0_lo{float(at(rng)), float(at(rng)), float(at(rng))};
    Vec3 x0_hi = x0_lo;
    x0_hi[a] += 1.0f;
    const Vec3 u_lo{u(rng), u(rng), u(rng)}, u_hi{u(rng), u(rng), u(rng)};
    const float v = link_violation(u_lo, u_hi, L, a);
    const double want = absolute_violation(x0_lo + u_lo, x0_hi + u_hi, L, a);
    ASSERT_NEAR(v, want, 1e-6) << "iteration " << it;
    outside += want > 0;
  }
  EXPECT_GT(outside, 1000) << "the cases must reach outside the box too";
}

TEST(LinkBoxDisplacements, IntervalIsTheAbsoluteIntervalMovedByRest) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> tau(0.005f, 1.0f), u(-2.0f, 2.0f);
  for (int it = 0; it < 20000; ++it) {
    const LinkLimits L = limits_from_tau(tau(rng), 1.0f);
    const int a = it % 3, side = (it / 3) % 2 ? 1 : -1, b = (it / 6) % 3;
    const Vec3 x0_e{3.0f, 4.0f, 5.0f};
    Vec3 x0_n = x0_e;
    x0_n[a] -= static_cast<float>(side);  // side +1: e = n + unit_a
    const Vec3 un{u(rng), u(rng), u(rng)};
    float lo, hi;
    link_interval(un, L, a, side, b, lo, hi);
    // Absolute: e's coordinate b within the box of n at X0_n + u_n.
    const double xn = static_cast<double>(x0_n[b]) + un[b];
    double alo, ahi;
    if (b != a) {
      alo = xn - L.shear;
      ahi = xn + L.shear;
    } else if (side > 0) {
      alo = xn + 1.0 + L.min_stretch;
      ahi = xn + 1.0 + L.max_stretch;
    } else {
      alo = xn - 1.0 - L.max_stretch;
      ahi = xn - 1.0 - L.min_stretch;
    }
    ASSERT_NEAR(x0_e[b] + static_cast<double>(lo), alo, 1e-6) << "iteration " << it;
    ASSERT_NEAR(x0_e[b] + static_cast<double>(hi), ahi, 1e-6) << "iteration " << it;
    // The restoration's bound is the same interval's end.
    ASSERT_EQ(solver::link_bound(un[b], L, a, side, b, true), hi);
    ASSERT_EQ(solver::link_bound(un[b], L, a, side, b, false), lo);
  }
}

TEST(LinkBoxDisplacements, ElementWallIsTheBoundaryBoxMovedByRest) {
  const solver::Wall w = solver::make_wall(Int3{1024, 48, 32}, 2.0f);
  for (const Int3 c : {Int3{0, 0, 0}, Int3{5, 47, 31}, Int3{1023, 20, 3}}) {
    const solver::Wall e = solver::element_wall(w, c.x, c.y, c.z);
    const int n[3] = {1024, 48, 32};
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(e.lo[a], -2.0f - float(c[a])) << "axis " << a;
      EXPECT_EQ(e.hi[a], float(n[a] - 1) + 2.0f - float(c[a])) << "axis " << a;
    }
  }
}
