// Every SIMD path's relaxation step against solver::relax_coordinate, bit for bit, on values
// where the step-back of the rounding rule matters: corrections a few float steps of the
// position long, both signs, signed zeros, denormals, and positions across the lattice range.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "cpu/kernels.hpp"
#include "solver/rules.hpp"

using namespace hpcm;

namespace {

struct StepCases {
  std::vector<float> s, sw, cur;
};

StepCases step_cases() {
  StepCases c;
  auto add = [&c](float s, float sw, float cur) {
    c.s.push_back(s);
    c.sw.push_back(sw);
    c.cur.push_back(cur);
  };
  const float positions[] = {0.0f, -0.0f, 1.0f, -1.0f, 0.5f, 3.0f, 63.75f, 127.99999f, 128.0f, 255.5f,
                             300.25f, -2.0f, 1e-20f, -1e-20f, 1e-39f /* denormal */};
  for (float cur : positions) {
    const float ulp = std::nextafter(std::fabs(cur), INFINITY) - std::fabs(cur);
    // Corrections of a fraction of a float step up to several, both signs; with weight sums
    // of 1 (q = s exactly) and of a few weights (the division rounds).
    for (int m = 1; m <= 12; ++m)
      for (float frac : {0.125f, 0.25f, 0.5f, 0.75f, 1.0f})
        for (float sign : {1.0f, -1.0f})
          for (float sw : {1.0f, 3.0f, 7.0f / 3.0f}) add(sign * frac * m * ulp * sw, sw, cur);
    for (float s : {0.0f, -0.0f, 1e-45f, -1e-45f, 1e-3f, -1e-3f, 0.37f, -2.5f}) add(s, 1.0f, cur);
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-300.0f, 300.0f), mant(-1.0f, 1.0f), w(0.5f, 6e4f);
  std::uniform_int_distribution<int> expo(0, 9);
  for (int i = 0; i < 4000; ++i) {
    const float sw = w(rng);
    add(mant(rng) * std::pow(10.0f, -static_cast<float>(expo(rng))) * sw, sw, pos(rng));
  }
  return c;
}

}  // namespace

TEST(CpuKernels, RelaxStepMatchesTheScalarRuleOnEveryPath) {
  std::vector<cpu::SimdKernels> paths{cpu::kernels_sse2()};
  if (cpu::cpu_has_avx2()) paths.push_back(cpu::kernels_avx2());
  if (cpu::cpu_has_avx512()) paths.push_back(cpu::kernels_avx512());
  const StepCases c = step_cases();
  const int n = static_cast<int>(c.s.size());
  for (float omega : {1.0f, 1.5f, 1.85f, 1.95f}) {
    std::vector<float> want(static_cast<std::size_t>(n));
    int stepped_back = 0;  // lanes where the rule's step-back applies: the case under test
    for (int i = 0; i < n; ++i) {
      const float q = c.s[i] / c.sw[i];
      want[i] = solver::relax_coordinate(c.cur[i], q, omega);
      const float plain = c.cur[i] + omega * q;
      if (std::memcmp(&want[i], &plain, sizeof(float)) != 0) ++stepped_back;
    }
    EXPECT_GT(stepped_back, 50) << "omega " << omega << ": too few cases exercise the step-back";
    for (const cpu::SimdKernels& k : paths) {
      std::vector<float> got(static_cast<std::size_t>(n), -7.0f);
      k.relax_step(c.s.data(), c.sw.data(), c.cur.data(), omega, got.data(), n);
      int differ = 0, first = -1;
      for (int i = 0; i < n; ++i)
        if (std::memcmp(&got[i], &want[i], sizeof(float)) != 0 && ++differ == 1) first = i;
      EXPECT_EQ(differ, 0) << k.name << ", omega " << omega << ": " << differ << " of " << n
                           << " lanes differ from the scalar rule; first: cur " << c.cur[first] << " s "
                           << c.s[first] << " sw " << c.sw[first];
    }
  }
}
