// Tissue classification (half-open thresholds) and the heterogeneous material interpolation.
#include <gtest/gtest.h>

#include <cmath>

#include "hpcm/material.hpp"
#include "hpcm/tissue.hpp"

using namespace hpcm;

namespace {

void expect_thresholds(const TissueThresholds& t) {
  // Half-open intervals: t-1 is below, t and t+1 are in the next class.
  EXPECT_EQ(t.classify(t.t1 - 1), Tissue::Air);
  EXPECT_EQ(t.classify(t.t1), Tissue::SkinFat);
  EXPECT_EQ(t.classify(t.t1 + 1), Tissue::SkinFat);
  EXPECT_EQ(t.classify(t.t2 - 1), Tissue::SkinFat);
  EXPECT_EQ(t.classify(t.t2), Tissue::MuscleOrgan);
  EXPECT_EQ(t.classify(t.t2 + 1), Tissue::MuscleOrgan);
  EXPECT_EQ(t.classify(t.t3 - 1), Tissue::MuscleOrgan);
  EXPECT_EQ(t.classify(t.t3), Tissue::Bone);
  EXPECT_EQ(t.classify(t.t3 + 1), Tissue::Bone);
}

TEST(Tissue, DefaultThresholdsAreThePapers) {
  const TissueThresholds t;
  EXPECT_EQ(t.t1, -1000.0f);
  EXPECT_EQ(t.t2, 25.0f);
  EXPECT_EQ(t.t3, 375.0f);
  expect_thresholds(t);
  EXPECT_EQ(t.classify(-3000.0f), Tissue::Air);
  EXPECT_EQ(t.classify(3000.0f), Tissue::Bone);
}

TEST(Tissue, RobustPresetAndCustomThresholds) {
  expect_thresholds(TissueThresholds::robust_preset());
  expect_thresholds(TissueThresholds{-600.0f, -20.0f, 150.0f});
  EXPECT_NO_THROW(TissueThresholds::robust_preset().validate());
}

TEST(Tissue, Names) {
  EXPECT_STREQ(tissue_name(Tissue::Air), "air");
  EXPECT_STREQ(tissue_name(Tissue::SkinFat), "skin_fat");
  EXPECT_STREQ(tissue_name(Tissue::MuscleOrgan), "muscle_organ");
  EXPECT_STREQ(tissue_name(Tissue::Bone), "bone");
}

std::string error_of(const TissueThresholds& t) {
  try {
    t.validate();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Tissue, InvalidThresholdsRejected) {
  EXPECT_NE(error_of({25.0f, 25.0f, 375.0f}).find("increasing"), std::string::npos);
  EXPECT_NE(error_of({-1000.0f, 400.0f, 375.0f}).find("increasing"), std::string::npos);
  EXPECT_NE(error_of({-1000.0f, 25.0f, std::nanf("")}).find("tissue.t3"), std::string::npos);
  EXPECT_NE(error_of({-INFINITY, 25.0f, 375.0f}).find("tissue.t1"), std::string::npos);
  EXPECT_EQ(error_of({-1000.0f, 25.0f, 375.0f}), "");
}

TEST(Material, ValuesAtControlPoints) {
  const MaterialTable m;
  for (const auto& p : m.points) {
    EXPECT_NEAR(m.tau(p.hu), p.tau, 1e-6f * p.tau + 1e-9f) << p.hu;
    EXPECT_NEAR(m.w(p.hu), p.w, 1e-6f) << p.hu;
  }
}

TEST(Material, TauInterpolatesInLogSpaceWLinearly) {
  MaterialTable m;
  m.points = {{0.0f, 0.4f, 1.0f}, {100.0f, 0.004f, 0.2f}};
  // Halfway: the geometric mean of tau (log space), the arithmetic mean of w.
  EXPECT_NEAR(m.tau(50.0f), std::sqrt(0.4f * 0.004f), 1e-6f);
  EXPECT_NEAR(m.w(50.0f), 0.6f, 1e-6f);
  // A quarter of the way: tau = 0.4 * 0.01^0.25.
  EXPECT_NEAR(m.tau(25.0f), 0.4f * std::pow(0.01f, 0.25f), 1e-6f);
  EXPECT_NEAR(m.w(25.0f), 0.8f, 1e-6f);
  // Constant beyond the ends.
  EXPECT_NEAR(m.tau(-500.0f), 0.4f, 1e-7f);
  EXPECT_NEAR(m.tau(900.0f), 0.004f, 1e-8f);
  EXPECT_NEAR(m.w(900.0f), 0.2f, 1e-7f);
  // Monotone between control points.
  float prev = m.tau(0.0f);
  for (float hu = 1.0f; hu <= 100.0f; hu += 1.0f) {
    EXPECT_LT(m.tau(hu), prev);
    prev = m.tau(hu);
  }
}

TEST(Material, LinkUsesMeanHuAndIsSymmetric) {
  const MaterialTable m;
  const LinkLimits a = m.link(-100.0f, 700.0f), b = m.link(700.0f, -100.0f);
  EXPECT_EQ(a.min_stretch, b.min_stretch);
  EXPECT_EQ(a.max_stretch, b.max_stretch);
  EXPECT_EQ(a.shear, b.shear);
  EXPECT_EQ(a.w, b.w);
  const float tau = m.tau(300.0f);
  EXPECT_NEAR(a.max_stretch, tau, 1e-6f);
  EXPECT_NEAR(a.min_stretch, -0.8f * tau, 1e-6f);
  EXPECT_NEAR(a.shear, tau, 1e-7f);
  EXPECT_NEAR(a.w, m.w(300.0f), 1e-7f);
  // SPEC §3 defaults: stiffer tissue has smaller tau and smaller w.
  EXPECT_GT(m.tau(-1000.0f), m.tau(-100.0f));
  EXPECT_GT(m.tau(-100.0f), m.tau(50.0f));
  EXPECT_GT(m.tau(50.0f), m.tau(700.0f));
  EXPECT_GT(m.w(50.0f), m.w(700.0f));
}

TEST(Material, LimitsFromTau) {
  const LinkLimits l = limits_from_tau(0.1f, 0.3f);
  EXPECT_NEAR(l.min_stretch, -0.08f, 1e-8f);
  EXPECT_NEAR(l.max_stretch, 0.1f, 1e-8f);
  EXPECT_EQ(l.shear, 0.1f);
  EXPECT_EQ(l.w, 0.3f);
}

}  // namespace
