// Parameter validation: every invalid value is rejected with an hpcm::Error that names its key.
#include <gtest/gtest.h>

#include <functional>

#include "hpcm/params.hpp"

using namespace hpcm;

namespace {

// Applies `change` to default params and expects validate() to throw an error naming `key`.
void expect_rejected(const std::function<void(Params&)>& change, const std::string& key) {
  Params p;
  change(p);
  try {
    p.validate();
    ADD_FAILURE() << "accepted an invalid " << key;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << "message '" << e.what() << "' does not name " << key;
  }
}

TEST(Params, DefaultsAreValid) { EXPECT_NO_THROW(Params{}.validate()); }

TEST(Params, InvalidControlPointsRejected) {
  expect_rejected([](Params& p) { p.material.points[1].tau = 0.0f; }, "material.points[1].tau");
  expect_rejected([](Params& p) { p.material.points[2].tau = 1.5f; }, "material.points[2].tau");
  expect_rejected([](Params& p) { p.material.points[0].w = 0.0f; }, "material.points[0].w");
  expect_rejected([](Params& p) { p.material.points[3].w = -1.0f; }, "material.points[3].w");
  expect_rejected([](Params& p) { p.material.points[2].hu = -200.0f; }, "material.points[2].hu");  // not increasing
  expect_rejected([](Params& p) { p.material.points[1].hu = std::nanf(""); }, "material.points[1].hu");
  expect_rejected([](Params& p) { p.material.points.resize(1); }, "material.points");
  expect_rejected([](Params& p) { p.material.points[0].tau = std::nanf(""); }, "material.points[0].tau");
}

TEST(Params, InvalidThresholdsRejected) {
  expect_rejected([](Params& p) { p.tissue.t2 = p.tissue.t1; }, "tissue");
  expect_rejected([](Params& p) { p.tissue.t3 = std::nanf(""); }, "tissue.t3");
}

TEST(Params, InvalidSolverAndDynamicsRejected) {
  expect_rejected([](Params& p) { p.solver.grab_radius = 0.0f; }, "solver.grab_radius");
  expect_rejected([](Params& p) { p.solver.brick_size = 6; }, "solver.brick_size");
  expect_rejected([](Params& p) { p.solver.relax_sweeps = -1; }, "solver.relax_sweeps");
  expect_rejected([](Params& p) { p.solver.relax_threshold = 1.0f; }, "solver.relax_threshold");
  expect_rejected([](Params& p) { p.solver.max_propagation_sweeps = 0; }, "solver.max_propagation_sweeps");
  expect_rejected([](Params& p) { p.dynamics.alpha = 1.2f; }, "dynamics.alpha");
  expect_rejected([](Params& p) { p.dynamics.b0 = -0.1f; }, "dynamics.b0");
  expect_rejected([](Params& p) { p.dynamics.b1[2] = 2.0f; }, "dynamics.b1.muscle_organ");
  expect_rejected([](Params& p) { p.dynamics.inverse_mass = {0, 0, 0, 0}; }, "dynamics.inverse_mass");
  expect_rejected([](Params& p) { p.dynamics.s_min = 0.8f, p.dynamics.s_max = 0.5f; }, "dynamics.s_min");
  expect_rejected([](Params& p) { p.dynamics.v_max = 0.0f; }, "dynamics.v_max");
  expect_rejected([](Params& p) { p.dynamics.beta = std::nanf(""); }, "dynamics.beta");
  expect_rejected([](Params& p) { p.dynamics.rho[1] = -1.0f; }, "dynamics.rho.skin_fat");
  expect_rejected([](Params& p) { p.dynamics.margin = 100.0f; }, "dynamics.margin");
  expect_rejected([](Params& p) { p.dynamics.dead_zone = -1e-3f; }, "dynamics.dead_zone");
}

TEST(Params, ModeNamesRoundTrip) {
  for (DampingMode m : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic})
    EXPECT_EQ(parse_damping_mode(damping_mode_name(m), "mode"), m);
  EXPECT_EQ(parse_damping_mode("B", "mode"), DampingMode::Simple);
  for (AnchorMode m : {AnchorMode::None, AnchorMode::Bone, AnchorMode::Border})
    EXPECT_EQ(parse_anchor_mode(anchor_mode_name(m), "anchors"), m);
  try {
    parse_damping_mode("fast", "dynamics.mode");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("dynamics.mode"), std::string::npos);
  }
}

TEST(Params, ResponseScale) {
  DynamicsParams d;
  d.inverse_mass = {1.0f, 1.0f, 0.15f, 0.0f};  // the paper's masses, independent of the defaults
  const PerTissue s = d.response_scale();
  EXPECT_FLOAT_EQ(s[0], 1.0f);
  EXPECT_FLOAT_EQ(s[1], 1.0f);
  EXPECT_FLOAT_EQ(s[2], 0.15f);
  EXPECT_FLOAT_EQ(s[3], 0.0f);
  d.inverse_mass = {2.0f, 4.0f, 1.0f, 0.0f};
  d.s_min = 0.3f;
  const PerTissue t = d.response_scale();
  EXPECT_FLOAT_EQ(t[0], 0.5f);
  EXPECT_FLOAT_EQ(t[1], 1.0f);
  EXPECT_FLOAT_EQ(t[2], 0.3f);  // 0.25 clamped to s_min
  EXPECT_FLOAT_EQ(t[3], 0.3f);
}

}  // namespace
