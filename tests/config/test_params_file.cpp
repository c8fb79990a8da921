// Parameter files: defaults round trip, exact round trip of arbitrary values, strict reading,
// and one named error per invalid value.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "hpcm/config.hpp"
#include "hpcm/param_table.hpp"

using hpcm::Params;
namespace cfg = hpcm::config;

namespace {

// Field-by-field comparison (names the field that differs), plus the defaulted operator== as
// a guard for fields added later.
void expect_params_eq(const Params& a, const Params& b) {
  EXPECT_EQ(a.tissue.t1, b.tissue.t1);
  EXPECT_EQ(a.tissue.t2, b.tissue.t2);
  EXPECT_EQ(a.tissue.t3, b.tissue.t3);
  ASSERT_EQ(a.material.points.size(), b.material.points.size());
  for (std::size_t i = 0; i < a.material.points.size(); ++i) {
    EXPECT_EQ(a.material.points[i].hu, b.material.points[i].hu) << "point " << i;
    EXPECT_EQ(a.material.points[i].tau, b.material.points[i].tau) << "point " << i;
    EXPECT_EQ(a.material.points[i].w, b.material.points[i].w) << "point " << i;
  }
  EXPECT_EQ(a.solver.grab_radius, b.solver.grab_radius);
  EXPECT_EQ(a.solver.brick_size, b.solver.brick_size);
  EXPECT_EQ(a.solver.relax_sweeps, b.solver.relax_sweeps);
  EXPECT_EQ(a.solver.relax_threshold, b.solver.relax_threshold);
  EXPECT_EQ(a.solver.anchors, b.solver.anchors);
  EXPECT_EQ(a.solver.max_propagation_sweeps, b.solver.max_propagation_sweeps);
  EXPECT_EQ(a.dynamics.mode, b.dynamics.mode);
  EXPECT_EQ(a.dynamics.alpha, b.dynamics.alpha);
  EXPECT_EQ(a.dynamics.b0, b.dynamics.b0);
  EXPECT_EQ(a.dynamics.b1, b.dynamics.b1);
  EXPECT_EQ(a.dynamics.inverse_mass, b.dynamics.inverse_mass);
  EXPECT_EQ(a.dynamics.s_min, b.dynamics.s_min);
  EXPECT_EQ(a.dynamics.s_max, b.dynamics.s_max);
  EXPECT_EQ(a.dynamics.dead_zone, b.dynamics.dead_zone);
  EXPECT_EQ(a.dynamics.v_max, b.dynamics.v_max);
  EXPECT_EQ(a.dynamics.beta, b.dynamics.beta);
  EXPECT_EQ(a.dynamics.rho, b.dynamics.rho);
  EXPECT_EQ(a.dynamics.margin, b.dynamics.margin);
  EXPECT_TRUE(a == b);
}

/// The hpcm::Error message of parse_params(text), or "" when it parses.
std::string error_of(const std::string& text, const std::string& source = "params.toml") {
  try {
    cfg::parse_params(text, source);
  } catch (const hpcm::Error& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_CONTAINS(hay, needle) EXPECT_NE(std::string(hay).find(needle), std::string::npos) << "message: " << (hay)

Params odd_params() {
  Params p;
  p.tissue = {-812.5f, 12.25f, 301.0f};
  p.material.points = {{-1024.f, 0.61f, 1.3f}, {-120.f, 0.31f, 0.7f}, {0.f, 0.2f, 0.4f}, {60.f, 0.1234567f, 0.3333333f},
                       {1200.f, 0.001f, 0.015f}};
  p.solver.grab_radius = 2.75f;
  p.solver.brick_size = 16;
  p.solver.relax_sweeps = 3;
  p.solver.relax_threshold = 3.3e-5f;
  p.solver.anchors = hpcm::AnchorMode::Border;
  p.solver.max_propagation_sweeps = 777;
  p.dynamics.mode = hpcm::DampingMode::Simple;
  p.dynamics.alpha = 0.1f;
  p.dynamics.b0 = 0.7f;
  p.dynamics.b1 = {0.01f, 0.2f, 0.3f, 0.99f};
  p.dynamics.inverse_mass = {0.5f, 1.0f, 0.001f, 1e-6f};
  p.dynamics.s_min = 0.05f;
  p.dynamics.s_max = 0.95f;
  p.dynamics.dead_zone = 3.3e-4f;  // at least 3e-4 under simple (it never comes to rest below)
  p.dynamics.v_max = 9.999f;
  p.dynamics.beta = 0.5f;  // beta * rho * s within the stability limit of alpha = 0.1 at 3 sweeps
  p.dynamics.rho = {0.0f, 0.5f, 1.5f, 2.0f};
  p.dynamics.margin = 0.5f;
  p.validate();
  return p;
}

}  // namespace

TEST(ParamsFile, DefaultsRoundTrip) {
  const std::string text = cfg::default_params_toml();
  const Params p = cfg::parse_params(text, "defaults.toml");
  expect_params_eq(p, Params{});
  // The writer is the same for any Params: the default file is params_to_toml(Params{}) up to
  // its header comment.
  const Params q = cfg::parse_params(cfg::params_to_toml(Params{}), "x.toml");
  expect_params_eq(q, Params{});
}

TEST(ParamsFile, DefaultFileDocumentsEveryKeyWithItsRange) {
  const std::string text = cfg::default_params_toml();
  for (const char* key : {"t1 = -1000.0", "t2 = 25.0", "t3 = 375.0", "grab_radius = 1.5", "brick_size = 8",
                          "relax_sweeps = 8", "relax_threshold = 0.03", "relax_slack = 1.0", "relax_omega = 1.85", "anchors = \"bone\"",
                          "max_propagation_sweeps = 100000", "grab_slip = true", "mode = \"viscoelastic\"", "alpha = 0.98", "b0 = 0.03",
                          "b1 = { air = 0.0, skin_fat = 0.15, muscle_organ = 0.15, bone = 0.15 }",
                          "inverse_mass = { air = 1.0, skin_fat = 1.0, muscle_organ = 0.15, bone = 0.0 }", "s_min = 0.0",
                          "s_max = 1.0", "dead_zone = 0.06", "v_max = 1.0", "beta = 1.0",
                          "rho = { air = 1.0, skin_fat = 1.0, muscle_organ = 1.0, bone = 1.0 }", "margin = 2.0", "sleep = true",
                          "sleep_speed = 1e-07",
                          "{ hu = -1000.0, tau = 0.5, w = 1.0 }", "{ hu = 700.0, tau = 0.005, w = 0.02 }", "preset"})
    EXPECT_CONTAINS(text, key);
  // Every "key = value" line carries a comment with its valid range or choices.
  std::istringstream in(text);
  std::string line;
  int key_lines = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line[0] == '[' || line[0] == ' ' || line[0] == ']') continue;
    if (line.rfind("points = [", 0) == 0) continue;  // the material array (its rows are commented)
    ++key_lines;
    const auto hash = line.find('#');
    ASSERT_NE(hash, std::string::npos) << "no comment on: " << line;
    const std::string comment = line.substr(hash);
    const bool has_range = comment.find('[') != std::string::npos || comment.find('(') != std::string::npos ||
                           comment.find('|') != std::string::npos || comment.find("<=") != std::string::npos ||
                           comment.find("HU") != std::string::npos;
    EXPECT_TRUE(has_range) << "no range on: " << line;
  }
  EXPECT_EQ(key_lines, 3 + 10 + 13);  // tissue + solver + dynamics keys; material points are an array
}

// Each key's line in the default file is written from the parameter table: in its section,
// with the table's range, unit and help as the comment.
TEST(ParamsFile, DefaultFileCommentsComeFromTheParameterTable) {
  const std::string text = cfg::default_params_toml();
  int keys = 0;
  for (const hpcm::ParamSpec& s : hpcm::param_table()) {
    if (s.type == hpcm::ParamType::Points || s.type == hpcm::ParamType::PointField) {
      EXPECT_CONTAINS(text, s.type == hpcm::ParamType::Points ? "points = [" : s.name() + " " + hpcm::range_text(s));
      continue;
    }
    const auto section = text.find("\n[" + s.section() + "]\n");
    ASSERT_NE(section, std::string::npos) << s.key;
    const auto next = text.find("\n[", section + 1);
    const auto line = text.find("\n" + s.name() + " = ", section);
    ASSERT_TRUE(line != std::string::npos && line < next) << s.key << " is not in its section";
    const std::string row = text.substr(line + 1, text.find('\n', line + 1) - line - 1);
    EXPECT_CONTAINS(row, "# ");
    EXPECT_CONTAINS(row, hpcm::range_text(s));
    EXPECT_CONTAINS(row, s.help);
    if (!s.unit.empty()) EXPECT_CONTAINS(row, s.unit);
    ++keys;
  }
  EXPECT_EQ(keys, 3 + 10 + 13);
}

TEST(ParamsFile, ExactRoundTripOfOddValues) {
  const Params p = odd_params();
  const Params q = cfg::parse_params(cfg::params_to_toml(p), "odd.toml");
  expect_params_eq(q, p);
  // Writing the parsed result again gives the same text.
  EXPECT_EQ(cfg::params_to_toml(q), cfg::params_to_toml(p));
}

TEST(ParamsFile, ExactRoundTripOfRandomFloats) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::uniform_int_distribution<int> mode(0, 2);
  for (int it = 0; it < 300; ++it) {
    Params p;
    p.tissue.t1 = -2000.0f + 1500.0f * u01(rng);
    p.tissue.t2 = p.tissue.t1 + 1.0f + 500.0f * u01(rng);
    p.tissue.t3 = p.tissue.t2 + 1e-3f + 900.0f * u01(rng);
    for (auto& mp : p.material.points) {
      mp.tau = std::max(1e-6f, u01(rng));
      mp.w = std::max(1e-6f, 100.0f * u01(rng));
    }
    p.solver.grab_radius = 1e-3f + 60.0f * u01(rng);
    p.solver.relax_threshold = 0.4f * u01(rng) * u01(rng);
    p.dynamics.mode = static_cast<hpcm::DampingMode>(mode(rng));
    p.dynamics.alpha = hpcm::kMaxSettlingAlpha * u01(rng);
    p.dynamics.b0 = std::max(hpcm::kMinSettlingB0, u01(rng));
    for (auto& v : p.dynamics.b1) v = u01(rng);
    for (auto& v : p.dynamics.inverse_mass) v = 0.001f + 5.0f * u01(rng);
    p.dynamics.s_min = 0.5f * u01(rng);
    p.dynamics.s_max = 0.5f + 0.5f * u01(rng);
    // At least kDeadZonePerThreshold thresholds (Params::validate rejects less with a velocity layer).
    p.dynamics.dead_zone = std::max(hpcm::kMinSettlingDeadZone, hpcm::kDeadZonePerThreshold * p.solver.relax_threshold) +
                           0.01f * u01(rng) * u01(rng) * u01(rng);
    p.dynamics.v_max = 1e-4f + 9.0f * u01(rng);
    p.dynamics.beta = 2.0f * u01(rng);
    for (auto& v : p.dynamics.rho) v = 2.0f * u01(rng);
    p.dynamics.margin = 64.0f * u01(rng);
    // Keep beta * rho * s within the stability limit (Params::validate rejects the rest).
    const hpcm::PerTissue sc = p.dynamics.response_scale();
    float worst = 0;
    for (int t = 0; t < hpcm::kTissueCount; ++t) worst = std::max(worst, p.dynamics.rho[t] * sc[t]);
    const float limit = p.dynamics.stable_gain_limit(p.solver.relax_omega, p.solver.relax_sweeps);
    if (worst > 0 && p.dynamics.beta * worst > limit) p.dynamics.beta = 0.999f * limit / worst;
    ASSERT_NO_THROW(p.validate()) << "iteration " << it;
    const std::string text = cfg::params_to_toml(p);
    Params q;
    ASSERT_NO_THROW(q = cfg::parse_params(text, "random.toml")) << text;
    ASSERT_TRUE(q == p) << "iteration " << it << "\n" << text;
  }
}

TEST(ParamsFile, MissingKeysKeepDefaults) {
  expect_params_eq(cfg::parse_params("", "empty.toml"), Params{});
  expect_params_eq(cfg::parse_params("# only a comment\n[dynamics]\n", "c.toml"), Params{});

  const Params p = cfg::parse_params(
      "[dynamics]\nalpha = 0.5\nb1 = { skin_fat = 0.25 }\nrho = 0.75\n[tissue]\nt1 = -900\n", "partial.toml");
  Params want;
  want.dynamics.alpha = 0.5f;
  want.dynamics.b1[1] = 0.25f;     // the other classes keep their defaults
  want.dynamics.rho.fill(0.75f);   // a single number sets every class
  want.tissue.t1 = -900.0f;        // integers are accepted for real-valued keys
  expect_params_eq(p, want);
}

TEST(ParamsFile, SubTablesAndArrayOfTablesForms) {
  const Params p = cfg::parse_params(
      "[dynamics.inverse_mass]\nmuscle_organ = 0.3\n"
      "[[material.points]]\nhu = -1000\ntau = 0.5\nw = 1\n"
      "[[material.points]]\nhu = 1000\ntau = 0.01\nw = 0.05\n",
      "forms.toml");
  EXPECT_EQ(p.dynamics.inverse_mass[2], 0.3f);
  ASSERT_EQ(p.material.points.size(), 2u);
  EXPECT_EQ(p.material.points[1].hu, 1000.0f);
  EXPECT_EQ(p.material.points[1].tau, 0.01f);
}

TEST(ParamsFile, ModesAnchorsAndPresets) {
  EXPECT_EQ(cfg::parse_params("[dynamics]\nmode = \"none\"", "m").dynamics.mode, hpcm::DampingMode::None);
  EXPECT_EQ(cfg::parse_params("[dynamics]\nmode = \"B\"", "m").dynamics.mode, hpcm::DampingMode::Simple);
  EXPECT_EQ(cfg::parse_params("[solver]\nanchors = \"bone\"", "m").solver.anchors, hpcm::AnchorMode::Bone);
  const Params r = cfg::parse_params("[tissue]\npreset = \"robust\"", "m");
  EXPECT_TRUE(r.tissue == hpcm::TissueThresholds::robust_preset());
  const Params r2 = cfg::parse_params("[tissue]\npreset = \"robust\"\nt3 = 300", "m");
  EXPECT_EQ(r2.tissue.t1, -500.0f);
  EXPECT_EQ(r2.tissue.t3, 300.0f);
  EXPECT_TRUE(cfg::parse_params("[tissue]\npreset = \"paper\"", "m").tissue == hpcm::TissueThresholds{});
}

TEST(ParamsFile, EachRangeViolationIsNamed) {
  struct Case {
    std::string text, key, range;
  };
  const std::vector<Case> cases = {
      {"[dynamics]\nalpha = 1.5", "dynamics.alpha", "[0, 1]"},
      {"[dynamics]\nalpha = -0.01", "dynamics.alpha", "[0, 1]"},
      {"[dynamics]\nb0 = 1.01", "dynamics.b0", "[0, 1]"},
      {"[dynamics]\nb1 = { muscle_organ = 2 }", "dynamics.b1.muscle_organ", "[0, 1]"},
      {"[dynamics]\ninverse_mass = { air = -1 }", "dynamics.inverse_mass.air", "[0, "},
      {"[dynamics]\ninverse_mass = 0", "dynamics.inverse_mass", "> 0"},
      {"[dynamics]\ns_min = 1.5", "dynamics.s_min", "[0, 1]"},
      {"[dynamics]\ns_max = -1", "dynamics.s_max", "[0, 1]"},
      {"[dynamics]\ns_min = 0.8\ns_max = 0.5", "dynamics.s_min", "dynamics.s_max"},
      {"[dynamics]\ndead_zone = 1.0", "dynamics.dead_zone", "[0, "},
      {"[dynamics]\nv_max = 0", "dynamics.v_max", "(0, 10]"},
      {"[dynamics]\nv_max = 11", "dynamics.v_max", "(0, 10]"},
      {"[dynamics]\nbeta = 3", "dynamics.beta", "[0, 2]"},
      {"[dynamics]\nrho = { bone = 2.5 }", "dynamics.rho.bone", "[0, 2]"},
      {"[dynamics]\nmargin = 100", "dynamics.margin", "[0, 64]"},
      {"[dynamics]\nmode = \"fast\"", "dynamics.mode", "none|simple|viscoelastic"},
      {"[solver]\ngrab_radius = 0", "solver.grab_radius", "(0, 64]"},
      {"[solver]\ngrab_radius = 65", "solver.grab_radius", "(0, 64]"},
      {"[solver]\nbrick_size = 6", "solver.brick_size", "4, 8 or 16"},
      {"[solver]\nrelax_sweeps = 300", "solver.relax_sweeps", "[0, 256]"},
      {"[solver]\nrelax_sweeps = -1", "solver.relax_sweeps", "[0, 256]"},
      {"[solver]\nrelax_threshold = 1.0", "solver.relax_threshold", "[0, "},
      {"[solver]\nmax_propagation_sweeps = 0", "solver.max_propagation_sweeps", "[1, 10000000]"},
      {"[solver]\nanchors = \"skin\"", "solver.anchors", "none|bone|border"},
      {"[tissue]\npreset = \"ct\"", "tissue.preset", "\"robust\""},
  };
  for (const auto& c : cases) {
    const std::string msg = error_of(c.text);
    ASSERT_FALSE(msg.empty()) << "accepted: " << c.text;
    EXPECT_EQ(msg.rfind("params.toml: ", 0), 0u) << msg;
    EXPECT_CONTAINS(msg, c.key);
    EXPECT_CONTAINS(msg, c.range);
  }
  // The spec example, verbatim, with the value's line appended.
  EXPECT_EQ(error_of("[dynamics]\nalpha = 1.5\n"), "params.toml: dynamics.alpha = 1.5 is out of range [0, 1] (line 2)");
}

TEST(ParamsFile, UnknownKeysAreErrors) {
  std::string m = error_of("[dynamics]\nalpah = 0.5\n");
  EXPECT_EQ(m.rfind("params.toml: ", 0), 0u) << m;
  EXPECT_CONTAINS(m, "unknown key 'dynamics.alpah'");
  EXPECT_CONTAINS(m, "did you mean 'dynamics.alpha'");
  EXPECT_CONTAINS(m, "(line 2)");

  m = error_of("[dynamcs]\nalpha = 0.5\n");
  EXPECT_CONTAINS(m, "unknown key 'dynamcs'");
  EXPECT_CONTAINS(m, "did you mean 'dynamics'");

  m = error_of("verbose = true\n");
  EXPECT_CONTAINS(m, "unknown key 'verbose'");
  EXPECT_CONTAINS(m, "tissue, material, solver, dynamics");

  m = error_of("[dynamics]\nb1 = { skin = 0.1 }\n");
  EXPECT_CONTAINS(m, "unknown key 'dynamics.b1.skin'");
  EXPECT_CONTAINS(m, "air, skin_fat, muscle_organ, bone");

  m = error_of("[material]\npoints = [{ hu = 0, tau = 0.1, w = 0.1, rho = 1 }, { hu = 1, tau = 0.1, w = 0.1 }]\n");
  EXPECT_CONTAINS(m, "unknown key 'material.points[0].rho'");

  m = error_of("[solver]\ngrab_radius = 1.5\nsweeps = 3\n");
  EXPECT_CONTAINS(m, "unknown key 'solver.sweeps'");
}

TEST(ParamsFile, WrongTypesAreErrors) {
  struct Case {
    std::string text, want;
  };
  const std::vector<Case> cases = {
      {"[dynamics]\nalpha = \"0.5\"", "dynamics.alpha must be a number, got a string \"0.5\""},
      {"[dynamics]\nalpha = true", "dynamics.alpha must be a number, got a boolean"},
      {"[solver]\nbrick_size = 8.0", "solver.brick_size must be an integer, got a float"},
      {"[solver]\nrelax_sweeps = \"8\"", "solver.relax_sweeps must be an integer"},
      {"[dynamics]\nmode = 1", "dynamics.mode must be a string, got an integer"},
      {"[solver]\nanchors = false", "solver.anchors must be a string"},
      {"[dynamics]\nb1 = [0, 0.5, 0.5, 0.5]", "dynamics.b1 must be a table"},
      {"[dynamics]\nrho = { bone = \"1\" }", "dynamics.rho.bone must be a number"},
      {"tissue = 5", "tissue must be a table, got an integer"},
      {"[tissue]\npreset = 1", "tissue.preset must be a string"},
      {"[material]\npoints = 3", "material.points must be an array"},
      {"[material]\npoints = [1, 2]", "material.points[0] must be a table"},
      {"[tissue]\nt1 = 1979-05-27", "tissue.t1 must be a number, got a date"},
  };
  for (const auto& c : cases) {
    const std::string msg = error_of(c.text);
    ASSERT_FALSE(msg.empty()) << "accepted: " << c.text;
    EXPECT_EQ(msg.rfind("params.toml: ", 0), 0u) << msg;
    EXPECT_CONTAINS(msg, c.want);
  }
}

TEST(ParamsFile, NonFiniteAndOverflowingNumbersAreErrors) {
  EXPECT_CONTAINS(error_of("[dynamics]\nalpha = nan"), "dynamics.alpha = nan is not a finite number");
  EXPECT_CONTAINS(error_of("[tissue]\nt1 = -inf"), "tissue.t1 = -inf is not a finite number");
  EXPECT_CONTAINS(error_of("[tissue]\nt3 = 1e300"), "tissue.t3 = 1e+300 is outside the single-precision range");
  EXPECT_CONTAINS(error_of("[solver]\nrelax_sweeps = 9999999999"), "does not fit in a 32-bit integer");
}

// A magnitude below FLT_MIN would silently become 0 (or lose precision): refused, 0 itself is fine.
TEST(ParamsFile, NumbersBelowTheSmallestFloatAreErrorsNotZero) {
  EXPECT_CONTAINS(error_of("[dynamics]\nalpha = 1e-50"),
                  "dynamics.alpha = 1e-50 is below the smallest positive single-precision value 1.1754944e-38");
  EXPECT_CONTAINS(error_of("[dynamics]\nb0 = -1e-40"), "dynamics.b0 = -1e-40 is below the smallest positive");
  EXPECT_EQ(error_of("[dynamics]\nalpha = 0.0"), "");
  EXPECT_EQ(error_of("[dynamics]\nalpha = 1.2e-38"), "");
}

TEST(ParamsFile, ThresholdsMustIncrease) {
  for (const char* text : {"[tissue]\nt1 = 0\nt2 = 0", "[tissue]\nt2 = 400", "[tissue]\nt1 = 500\nt2 = 100\nt3 = 50",
                           "[tissue]\npreset = \"robust\"\nt2 = -600"}) {
    const std::string m = error_of(text);
    EXPECT_EQ(m.rfind("params.toml: ", 0), 0u) << m;
    EXPECT_CONTAINS(m, "tissue");
    EXPECT_CONTAINS(m, "strictly increasing");
  }
}

TEST(ParamsFile, BadControlPoints) {
  std::string m = error_of("[material]\npoints = [{ hu = 0, tau = 0.1, w = 0.1 }]");
  EXPECT_CONTAINS(m, "material.points");
  EXPECT_CONTAINS(m, "at least 2");
  m = error_of("[material]\npoints = []");
  EXPECT_CONTAINS(m, "at least 2");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 0.1, w = 0.1 }, { hu = 0, tau = 0.05, w = 0.1 }]");
  EXPECT_CONTAINS(m, "material.points[1].hu");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 0.1, w = 0.1 }, { hu = -10, tau = 0.05, w = 0.1 }]");
  EXPECT_CONTAINS(m, "material.points[1].hu");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 0, w = 0.1 }, { hu = 10, tau = 0.05, w = 0.1 }]");
  EXPECT_CONTAINS(m, "material.points[0].tau");
  EXPECT_CONTAINS(m, "(0, 1]");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 1.5, w = 0.1 }, { hu = 10, tau = 0.05, w = 0.1 }]");
  EXPECT_CONTAINS(m, "(0, 1]");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 0.5, w = 0.1 }, { hu = 10, tau = 0.05, w = -1 }]");
  EXPECT_CONTAINS(m, "material.points[1].w");
  EXPECT_CONTAINS(m, "[1e-06, 100]");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 0.5, w = 0.1 }, { hu = 10, tau = 0.05, w = 9e-7 }]");
  EXPECT_CONTAINS(m, "material.points[1].w = 9e-07 is out of range [1e-06, 100]");
  m = error_of("[material]\npoints = [{ hu = 0, tau = 0.5 }, { hu = 10, tau = 0.05, w = 1 }]");
  EXPECT_CONTAINS(m, "material.points[0] is missing 'w'");
}

TEST(ParamsFile, SyntaxErrorsNameFileAndLine) {
  const std::string m = error_of("[dynamics]\nalpha = = 0.5\n", "my params.toml");
  EXPECT_EQ(m.rfind("my params.toml: line 2, column", 0), 0u) << m;
  EXPECT_CONTAINS(m, "TOML syntax error");
  EXPECT_CONTAINS(error_of("[dynamics]\nalpha = 0.5\nalpha = 0.6\n"), "line 3");  // duplicate key
}

TEST(ParamsFile, LoadFromDisk) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("hpcm_cfg_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" + std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  const fs::path f = dir / "p.toml";
  {
    std::ofstream o(f);
    o << cfg::params_to_toml(odd_params());
  }
  expect_params_eq(cfg::load_params(f.string()), odd_params());
  {
    std::ofstream o(f);
    o << "[dynamics]\nalpha = 1.5\n";
  }
  try {
    cfg::load_params(f.string());
    ADD_FAILURE() << "accepted alpha = 1.5";
  } catch (const hpcm::Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(f.string() + ": dynamics.alpha = 1.5", 0), 0u) << e.what();
  }
  try {
    cfg::load_params((dir / "missing.toml").string());
    ADD_FAILURE() << "opened a missing file";
  } catch (const hpcm::Error& e) {
    EXPECT_CONTAINS(e.what(), "missing.toml: cannot open");
  }
  fs::remove_all(dir);
}

TEST(ParamsFile, ExampleParameterFilesParse) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(HPCM_SOURCE_DIR) / "examples";
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("params_", 0) != 0 || e.path().extension() != ".toml") continue;
    EXPECT_NO_THROW(cfg::load_params(e.path().string())) << name;
    ++n;
  }
  EXPECT_GE(n, 1) << "no examples/params_*.toml found";
}
