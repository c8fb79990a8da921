// Scenario keyframes and grab radii in millimetres (issue 32, item 2): converted with the
// lattice spacing per axis, so the same scenario pulls the same physical distance whatever the
// down-sampling, while lattice units scale with it. Out-of-range millimetres name the field.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "hpcm/phantom.hpp"
#include "hpcm/scenario.hpp"
#include "hpcm/simulation.hpp"

using namespace hpcm;

namespace {

#define EXPECT_CONTAINS(hay, needle) EXPECT_NE(std::string(hay).find(needle), std::string::npos) << "message: " << (hay)

/// The thick-slice phantom (0.8 : 0.8 : 5 spacing) down-sampled by f.
Model anisotropic_model(int f) {
  PhantomOptions o;
  o.dims = {64, 64, 24};
  o.variant = PhantomVariant::Anisotropic;
  const Volume v = make_phantom(o);
  return build_model(f == 1 ? v : downsample(v, f), Params{});
}

/// One grab at the paper's point, pulled over `pull` frames to the keyframe and held.
Scenario pull_scenario(Vec3 offset, Units units, float radius, Units radius_units, int pull = 10) {
  Scenario s;
  s.name = "units";
  GrabAction g;
  g.radius = radius;
  g.radius_units = radius_units;
  g.release = pull + 5;
  g.path = {{pull, offset, units}};
  s.grabs.push_back(g);
  s.frames = pull + 1;
  return s;
}

struct Pull {
  double centre_mm[3];   ///< displacement of the grab centre along x, y, z, mm
  double cell_mm;        ///< largest lattice spacing, mm
  double grabbed_reach_mm[3];  ///< farthest grabbed element from the centre along x, y, z, mm
  bool limited;
};

Pull play(const Model& m, const Scenario& sc) {
  Simulation sim(m, Params{});
  ScenarioPlayer player(sc, sim);
  while (!player.done()) player.step();
  EXPECT_TRUE(sim.grabbing());
  Pull p{};
  const Index c = sim.grab_centre();
  const Vec3 d = sim.state().disp[static_cast<std::size_t>(c)];
  const Int3 cc = m.coords(c);
  for (int a = 0; a < 3; ++a) p.centre_mm[a] = d[a] * m.spacing[a];
  for (Index g : sim.grabbed()) {
    const Int3 gc = m.coords(g);
    const int off[3] = {gc.x - cc.x, gc.y - cc.y, gc.z - cc.z};
    for (int a = 0; a < 3; ++a) p.grabbed_reach_mm[a] = std::max(p.grabbed_reach_mm[a], std::abs(off[a]) * m.spacing[a]);
  }
  p.cell_mm = std::max({m.spacing[0], m.spacing[1], m.spacing[2]});
  p.limited = sim.tool_limited();
  return p;
}

}  // namespace

TEST(ScenarioUnits, MillimetresPullTheSameDistanceAtEveryDownsample) {
  const Model m1 = anisotropic_model(1), m2 = anisotropic_model(2);
  ASSERT_GT(m1.spacing[2], 5 * m1.spacing[0]) << "the phantom must be anisotropic";
  ASSERT_NEAR(m2.spacing[1], 2 * m1.spacing[1], 1e-9);
  RecordProperty("spacing_f1", std::to_string(m1.spacing[0]) + " x " + std::to_string(m1.spacing[1]) + " x " +
                                   std::to_string(m1.spacing[2]) + " mm");
  const Vec3 mm{6.0f, -30.0f, 8.0f};
  const Pull p1 = play(m1, pull_scenario(mm, Units::mm, 15.0f, Units::mm));
  const Pull p2 = play(m2, pull_scenario(mm, Units::mm, 15.0f, Units::mm));
  ASSERT_FALSE(p1.limited);
  ASSERT_FALSE(p2.limited);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(p1.centre_mm[a], mm[a], 1e-3 * p1.cell_mm) << "axis " << a << " at f = 1";
    EXPECT_NEAR(p2.centre_mm[a], mm[a], 1e-3 * p2.cell_mm) << "axis " << a << " at f = 2";
    EXPECT_NEAR(p1.centre_mm[a], p2.centre_mm[a], p2.cell_mm) << "axis " << a;
    // The grab holds a 15 mm sphere: nothing farther, and as far as the lattice allows.
    EXPECT_LE(p1.grabbed_reach_mm[a], 15.0 + 1e-6) << "axis " << a;
    EXPECT_LE(p2.grabbed_reach_mm[a], 15.0 + 1e-6) << "axis " << a;
    EXPECT_GT(p1.grabbed_reach_mm[a], 15.0 - m1.spacing[a] - 1e-6) << "axis " << a;
    EXPECT_GT(p2.grabbed_reach_mm[a], 15.0 - m2.spacing[a] - 1e-6) << "axis " << a;
  }
  // The same pull in lattice units moves twice as far at f = 2: why millimetres exist.
  const Vec3 lattice = lattice_offset_of_mm(m1, {0, -15, 0});
  const Pull l1 = play(m1, pull_scenario(lattice, Units::lattice, 0, Units::lattice));
  const Pull l2 = play(m2, pull_scenario(lattice, Units::lattice, 0, Units::lattice));
  ASSERT_FALSE(l2.limited);
  EXPECT_NEAR(l1.centre_mm[1], -15, 1e-3 * l1.cell_mm);
  EXPECT_NEAR(l2.centre_mm[1], -30, 1e-3 * l2.cell_mm);
}

TEST(ScenarioUnits, ConversionIsPerAxisAndKeepsLatticeKeyframes) {
  Model m = anisotropic_model(2);
  Scenario s = pull_scenario({5, -10, 20}, Units::mm, 0, Units::lattice);
  s.grabs[0].path.insert(s.grabs[0].path.begin(), Keyframe{2, {0, -1, 0}, Units::lattice});
  const Scenario l = s.in_lattice_units(m);
  ASSERT_EQ(l.grabs[0].path.size(), 2u);
  EXPECT_TRUE(l.grabs[0].path[0].offset == (Vec3{0, -1, 0}));
  for (const Keyframe& kf : l.grabs[0].path) EXPECT_EQ(kf.units, Units::lattice);
  const Vec3 o = l.grabs[0].path[1].offset;
  EXPECT_FLOAT_EQ(o.x, static_cast<float>(5 / m.spacing[0]));
  EXPECT_FLOAT_EQ(o.y, static_cast<float>(-10 / m.spacing[1]));
  EXPECT_FLOAT_EQ(o.z, static_cast<float>(20 / m.spacing[2]));
  // The paper protocol keeps its lattice definition.
  const Scenario paper = Scenario::paper_protocol();
  EXPECT_EQ(paper.grabs[0].radius_units, Units::lattice);
  EXPECT_EQ(paper.grabs[0].path.back().units, Units::lattice);
  EXPECT_TRUE(paper.in_lattice_units(m).grabs[0].path.back().offset == (Vec3{0, -6, 0}));
}

TEST(ScenarioUnits, MillimetresOutOfRangeNameTheFieldAndRange) {
  const Model m = anisotropic_model(2);
  auto error_of = [&](const Scenario& s) -> std::string {
    try {
      Simulation sim(m, Params{});
      ScenarioPlayer player(s, sim);
      while (!player.done()) player.step();
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_CONTAINS(error_of(pull_scenario({0, -5, 0}, Units::mm, -1.0f, Units::mm)),
                  "grab[0].radius_mm = -1 is out of range: it must be > 0 mm and at most 64 lattice units along every axis");
  EXPECT_CONTAINS(error_of(pull_scenario({0, -5, 0}, Units::mm, nan, Units::mm)), "grab[0].radius_mm = nan is out of range");
  // 64 lattice units along the finest axis is the largest radius on this lattice.
  const double most_mm = 64 * std::min({m.spacing[0], m.spacing[1], m.spacing[2]});
  EXPECT_CONTAINS(error_of(pull_scenario({0, -5, 0}, Units::mm, static_cast<float>(most_mm * 1.01), Units::mm)),
                  "mm on this lattice)");
  EXPECT_CONTAINS(error_of(pull_scenario({0, -1e9f, 0}, Units::mm, 0, Units::lattice)),
                  "grab[0].keyframes[0].offset_mm (0, -1e+09, 0) mm is out of range: at most "
                  "10000 lattice units per axis");

  // Simulation::grab_mm directly (Python's grab(radius_mm=...)).
  Simulation sim(m, Params{});
  for (float bad : {-2.0f, 0.0f, nan, std::numeric_limits<float>::infinity()}) {
    try {
      sim.grab_mm(paper_grab_centre(m), bad);
      ADD_FAILURE() << "radius_mm " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_CONTAINS(e.what(), "radius_mm = ");
      EXPECT_CONTAINS(e.what(), "must be > 0 mm and at most 64 lattice units along every axis");
    }
    EXPECT_FALSE(sim.grabbing());
  }
}
