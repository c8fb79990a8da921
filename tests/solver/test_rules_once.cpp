// The rules written once over the lane type (hpcm/material.hpp box_from_tau, core/link_box.hpp
// link_interval / link_axis_excess / link_violation, solver/rules.hpp relax_coordinate): every
// SIMD width's instantiation (4, 8 and 16 lanes, as far as this CPU runs them; the AVX-512
// relax_coordinate is a hand-written specialisation) against the float instantiation, which is
// what the scalar CPU code and the CUDA kernels compile, bit for bit; and the float
// instantiation against the rules as they read before they were written over lanes (nextafterf,
// the branchy box test), so results stay what they were.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "core/link_box.hpp"
#include "cpu/kernels.hpp"
#include "solver/rules.hpp"

using namespace hpcm;

namespace {

std::uint32_t bits_of(float x) {
  std::uint32_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}
bool same_bits(float a, float b) { return bits_of(a) == bits_of(b); }
std::string describe(float x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g (0x%08x)", static_cast<double>(x), bits_of(x));
  return buf;
}

std::vector<cpu::SimdKernels> every_path() {
  std::vector<cpu::SimdKernels> paths{cpu::kernels_sse2()};
  if (cpu::cpu_has_avx2()) paths.push_back(cpu::kernels_avx2());
  if (cpu::cpu_has_avx512()) paths.push_back(cpu::kernels_avx512());
  return paths;
}

constexpr float kDenormMin = 1.4e-45f;

/// Values at the edges of float: signed zeros, denormals, the smallest normal, the largest
/// finite, infinities.
std::vector<float> edge_values() {
  std::vector<float> v;
  for (float x : {0.0f, kDenormMin, 2 * kDenormMin, 3 * kDenormMin, 7 * kDenormMin, 1e-39f, FLT_MIN,
                  1e-20f, 1e-7f, 0.125f, 0.5f, 1.0f, 1.5f, 3.0f, 63.75f, 127.99999f, 128.0f, 300.25f,
                  1e20f, 1e30f, FLT_MAX, INFINITY})
    for (float s : {1.0f, -1.0f}) v.push_back(s * x);
  return v;
}

// ---------------------------------------------------------------------------------------------
// relax_coordinate
// ---------------------------------------------------------------------------------------------

/// The rule as it was written for float before it was written over lanes: round to nearest,
/// and where that lengthened the step to (2 + omega) / 2 times q or more, nextafterf toward cur.
float relax_coordinate_as_specified(float cur, float q, float omega) {
  const float t = cur + omega * q;
  const float d = t - cur;
  const float limit = (0.5f * (2.0f + omega)) * q;
  if ((q > 0.0f ? d >= limit : d <= limit) && q != 0.0f) return std::nextafter(t, cur);
  return t;
}

struct StepCases {
  std::vector<float> s, sw, cur;
  void add(float s_, float sw_, float cur_) {
    s.push_back(s_);
    sw.push_back(sw_);
    cur.push_back(cur_);
  }
};

/// Steps of every size at edge positions, steps that land exactly on zero (cur = -(omega q) for
/// q a few denormals: the step back must then leave zero on cur's side), huge and infinite
/// operands, NaN, and random steps a few float steps long.
StepCases step_cases(float omega) {
  StepCases c;
  const std::vector<float> edges = edge_values();
  for (float cur : edges)
    for (float q : edges) c.add(q, 1.0f, cur);  // sw = 1: q = s exactly
  for (float cur : edges) {
    c.add(NAN, 1.0f, cur);
    c.add(1.0f, 1.0f, NAN);
  }
  for (int m = 1; m <= 40; ++m)
    for (float sign : {1.0f, -1.0f}) {
      const float q = sign * static_cast<float>(m) * kDenormMin;
      c.add(q, 1.0f, -(omega * q));  // t = cur + omega q = 0 exactly
      c.add(q, 1.0f, -(omega * q) + kDenormMin);
      c.add(q, 1.0f, -(omega * q) - kDenormMin);
    }
  for (float cur : edges) {
    if (!std::isfinite(cur)) continue;
    const float ulp = std::nextafter(std::fabs(cur), INFINITY) - std::fabs(cur);
    for (int m = 1; m <= 12; ++m)
      for (float frac : {0.125f, 0.25f, 0.5f, 0.75f, 1.0f})
        for (float sign : {1.0f, -1.0f})
          for (float sw : {1.0f, 3.0f, 7.0f / 3.0f}) c.add(sign * frac * static_cast<float>(m) * ulp * sw, sw, cur);
  }
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> pos(-300.0f, 300.0f), mant(-1.0f, 1.0f), w(0.5f, 6e4f);
  std::uniform_int_distribution<int> expo(0, 12);
  for (int i = 0; i < 20000; ++i) {
    const float sw = w(rng), cur = pos(rng);
    c.add(mant(rng) * std::pow(10.0f, -static_cast<float>(expo(rng))) * sw, sw, cur);
    const float ulp = std::nextafter(std::fabs(cur), INFINITY) - std::fabs(cur);
    c.add(mant(rng) * 8.0f * ulp, 1.0f, cur);  // a few float steps: the step back matters
  }
  return c;
}

}  // namespace

// The float definition (what relax_element, the CPU's scalar path and the CUDA kernels run) is
// nextafterf toward cur wherever the step is cut back, at every edge of float.
TEST(RulesOnce, RelaxCoordinateIsTheSpecifiedRounding) {
  for (float omega : {1.0f, 1.5f, 1.85f, 1.95f}) {
    const StepCases c = step_cases(omega);
    int stepped_back = 0, onto_zero = 0;
    for (std::size_t i = 0; i < c.s.size(); ++i) {
      const float q = c.s[i] / c.sw[i];
      const float want = relax_coordinate_as_specified(c.cur[i], q, omega);
      const float got = solver::relax_coordinate(c.cur[i], q, omega);
      ASSERT_TRUE(same_bits(got, want)) << "omega " << omega << " cur " << describe(c.cur[i]) << " q " << describe(q)
                                        << ": got " << describe(got) << ", specified " << describe(want);
      const float plain = c.cur[i] + omega * q;
      if (!same_bits(want, plain)) {
        ++stepped_back;
        onto_zero += plain == 0.0f;
      }
    }
    EXPECT_GT(stepped_back, 100) << "omega " << omega << ": too few cases exercise the step back";
    if (omega > 1.5f) {
      EXPECT_GT(onto_zero, 0) << "omega " << omega << ": no case steps back from zero";
    }
  }
}

// Every SIMD width's relax_coordinate (the one its relaxation kernel calls) against the float
// definition, bit for bit. Before the rule was written once, the vector step back from a step
// that landed on zero went to -0 - 1 on the bit pattern (a NaN) or to the wrong side of zero.
TEST(RulesOnce, RelaxCoordinateEveryWidthMatchesTheDefinition) {
  for (const cpu::SimdKernels& k : every_path())
    for (float omega : {1.0f, 1.5f, 1.85f, 1.95f}) {
      const StepCases c = step_cases(omega);
      const int n = static_cast<int>(c.s.size());
      std::vector<float> got(static_cast<std::size_t>(n), -7.0f);
      k.relax_step(c.s.data(), c.sw.data(), c.cur.data(), omega, got.data(), n);
      int differ = 0;
      std::string first;
      for (int i = 0; i < n; ++i) {
        const float want = solver::relax_coordinate(c.cur[i], c.s[i] / c.sw[i], omega);
        if (!same_bits(got[i], want) && ++differ == 1)
          first = "cur " + describe(c.cur[i]) + " s " + describe(c.s[i]) + " sw " + describe(c.sw[i]) + ": got " +
                  describe(got[i]) + ", definition " + describe(want);
      }
      EXPECT_EQ(differ, 0) << k.name << ", omega " << omega << ": " << differ << " of " << n << " lanes differ; first: " << first;
    }
}

// ---------------------------------------------------------------------------------------------
// The link box
// ---------------------------------------------------------------------------------------------

namespace {

/// The link box test as it was written for float before it was written over lanes.
float axis_excess_as_specified(float d, const LinkLimits& L, bool axial) {
  if (axial) return d < L.min_stretch ? L.min_stretch - d : (d > L.max_stretch ? d - L.max_stretch : 0.0f);
  const float ad = d < 0 ? -d : d;
  return ad > L.shear ? ad - L.shear : 0.0f;
}
float violation_as_specified(const float (&d)[3], const LinkLimits& L, int a) {
  float v = 0.0f;
  for (int b = 0; b < 3; ++b) {
    const float e = axis_excess_as_specified(d[b], L, b == a);
    v = e > v ? e : v;
  }
  return v;
}

struct LinkCases {
  std::vector<float> tau, c, d[3];
  void add(float t, float c_, float d0, float d1, float d2) {
    tau.push_back(t);
    c.push_back(c_);
    d[0].push_back(d0);
    d[1].push_back(d1);
    d[2].push_back(d2);
  }
};

/// Tolerances from 0 (the model's "no link" entry) and denormals to 1 and beyond; differences at
/// the edges of float and exactly on, just inside and just outside each box limit.
LinkCases link_cases() {
  LinkCases lc;
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> tau_r(0.005f, 1.0f), u(-1.5f, 1.5f);
  std::vector<float> taus = {0.0f, kDenormMin, 1e-39f, 0.005f, 0.02f, 0.22f, 0.35f, 0.4f, 0.5f, 1.0f, 2.0f};
  for (int i = 0; i < 40; ++i) taus.push_back(tau_r(rng));
  const std::vector<float> edges = edge_values();
  for (float tau : taus) {
    const LinkLimits L = limits_from_tau(tau, 1.0f);
    std::vector<float> ds = edges;
    for (float x : {L.min_stretch, L.max_stretch, L.shear, -L.shear})
      for (float y : {x, std::nextafter(x, INFINITY), std::nextafter(x, -INFINITY)}) ds.push_back(y);
    ds.push_back(NAN);
    for (std::size_t i = 0; i < ds.size(); ++i)
      for (std::size_t j = 0; j < ds.size(); j += 3) lc.add(tau, ds[j], ds[i], ds[j], ds[(i + j) % ds.size()]);
  }
  for (int i = 0; i < 20000; ++i) lc.add(tau_r(rng), u(rng), u(rng), u(rng), u(rng));
  return lc;
}

}  // namespace

// The float definitions of the box, its interval and its excess give what they gave before they
// were written over lanes (so the model's link table, the restoration's bounds and the metrics
// are unchanged), at the edges of float too.
TEST(RulesOnce, LinkBoxIsTheSpecifiedTest) {
  const LinkCases lc = link_cases();
  for (std::size_t i = 0; i < lc.tau.size(); ++i) {
    const float tau = lc.tau[i];
    const LinkLimits L = limits_from_tau(tau, 1.0f);
    const float cap = 0.5f * (0.98f - 0.8f * tau);
    ASSERT_TRUE(same_bits(L.min_stretch, -(0.8f * tau)) && same_bits(L.max_stretch, tau) &&
                same_bits(L.shear, tau < cap ? tau : cap))
        << "tau " << describe(tau);
    const float d[3] = {lc.d[0][i], lc.d[1][i], lc.d[2][i]};
    for (int a = 0; a < 3; ++a) {
      ASSERT_TRUE(same_bits(link_axis_excess(d[a], L, true), axis_excess_as_specified(d[a], L, true))) << "d " << describe(d[a]);
      ASSERT_TRUE(same_bits(link_axis_excess(d[a], L, false), axis_excess_as_specified(d[a], L, false))) << "d " << describe(d[a]);
      ASSERT_TRUE(same_bits(link_violation(d, L, a), violation_as_specified(d, L, a)))
          << "tau " << describe(tau) << " axis " << a << " d " << describe(d[0]) << " " << describe(d[1]) << " " << describe(d[2]);
      // The element form: d from the two ends' displacements.
      const Vec3 lo{0.0f, 0.0f, 0.0f}, hi{d[0], d[1], d[2]};
      ASSERT_TRUE(same_bits(link_violation(lo, hi, L, a), link_violation(d, L, a)));
    }
  }
}

// Every SIMD width's box_from_tau, link_interval, link_axis_excess and link_violation (the ones
// its relaxation and link-check kernels call) against the float definitions, bit for bit.
TEST(RulesOnce, LinkRulesEveryWidthMatchTheDefinition) {
  const LinkCases lc = link_cases();
  const int n = static_cast<int>(lc.tau.size());
  for (const cpu::SimdKernels& k : every_path())
    for (int axis = 0; axis < 3; ++axis)
      for (bool axial : {true, false})
        for (int side : {+1, -1}) {
          std::vector<float> out[7];
          for (auto& o : out) o.assign(static_cast<std::size_t>(n), -7.0f);
          const cpu::LinkRuleLanes io{lc.tau.data(), lc.c.data(), {lc.d[0].data(), lc.d[1].data(), lc.d[2].data()},
                                      out[0].data(), out[1].data(), out[2].data(), out[3].data(), out[4].data(),
                                      out[5].data(), out[6].data()};
          k.link_rules(io, axial, side, axis, n);
          int differ = 0;
          std::string first;
          for (int i = 0; i < n; ++i) {
            const LinkBox<float> box = box_from_tau(lc.tau[i]);
            float lo, hi;
            link_interval(lc.c[i], box, axial, side, lo, hi);
            const float d[3] = {lc.d[0][i], lc.d[1][i], lc.d[2][i]};
            const float want[7] = {box.min_stretch, box.max_stretch, box.shear, lo, hi,
                                   link_axis_excess(d[0], box, axial), link_violation(d, box, axis)};
            for (int f = 0; f < 7; ++f)
              if (!same_bits(out[f][static_cast<std::size_t>(i)], want[f]) && ++differ == 1)
                first = "output " + std::to_string(f) + " tau " + describe(lc.tau[i]) + " c " + describe(lc.c[i]) + " d " +
                        describe(d[0]) + " " + describe(d[1]) + " " + describe(d[2]) + ": got " +
                        describe(out[f][static_cast<std::size_t>(i)]) + ", definition " + describe(want[f]);
          }
          EXPECT_EQ(differ, 0) << k.name << ", axis " << axis << (axial ? " axial" : " across") << " side " << side << ": "
                               << differ << " outputs differ; first: " << first;
        }
}
