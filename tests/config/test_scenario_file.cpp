// Scenario files: grabs with keyframes, the paper-protocol shortcut, round trip, and errors.
#include <gtest/gtest.h>

#include <filesystem>

#include "hpcm/config.hpp"

using hpcm::Scenario;
namespace cfg = hpcm::config;

namespace {

void expect_scenario_eq(const Scenario& a, const Scenario& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.frames, b.frames);
  ASSERT_EQ(a.grabs.size(), b.grabs.size());
  for (std::size_t k = 0; k < a.grabs.size(); ++k) {
    const auto& g = a.grabs[k];
    const auto& h = b.grabs[k];
    EXPECT_EQ(g.centre.has_value(), h.centre.has_value()) << "grab " << k;
    if (g.centre && h.centre) EXPECT_TRUE(*g.centre == *h.centre) << "grab " << k;
    EXPECT_EQ(g.radius, h.radius) << "grab " << k;
    EXPECT_EQ(g.radius_units, h.radius_units) << "grab " << k;
    EXPECT_EQ(g.start, h.start) << "grab " << k;
    EXPECT_EQ(g.release, h.release) << "grab " << k;
    ASSERT_EQ(g.path.size(), h.path.size()) << "grab " << k;
    for (std::size_t i = 0; i < g.path.size(); ++i) {
      EXPECT_EQ(g.path[i].frame, h.path[i].frame) << "grab " << k << " key " << i;
      EXPECT_TRUE(g.path[i].offset == h.path[i].offset) << "grab " << k << " key " << i;
      EXPECT_EQ(g.path[i].units, h.path[i].units) << "grab " << k << " key " << i;
    }
  }
}

std::string scenario_error_of(const std::string& text) {
  try {
    cfg::parse_scenario(text, "scn.toml");
  } catch (const hpcm::Error& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_CONTAINS(hay, needle) EXPECT_NE(std::string(hay).find(needle), std::string::npos) << "message: " << (hay)

const char* kTwoGrabs = R"(
[scenario]
name = "two grabs"
frames = 200

[[grab]]
centre = "auto"
start = 0
release = 30
keyframes = [[20, 0, -6, 0], [30, 0, -6, 0]]

[[grab]]
centre = [40, 12, 20]
radius = 2.5
start = 100
release = 25
keyframes = [
  [10, 3.5, 0.0, 0.0],   # sideways
  [20, 3.5, 0.0, -2.25],
]
)";

}  // namespace

TEST(ScenarioFile, ParsesGrabsAndKeyframes) {
  const Scenario s = cfg::parse_scenario(kTwoGrabs, "two.toml");
  EXPECT_EQ(s.name, "two grabs");
  EXPECT_EQ(s.frames, 200);
  ASSERT_EQ(s.grabs.size(), 2u);
  EXPECT_FALSE(s.grabs[0].centre.has_value());
  EXPECT_EQ(s.grabs[0].radius, 0.0f);  // default: params.solver.grab_radius
  EXPECT_EQ(s.grabs[0].release, 30);
  ASSERT_EQ(s.grabs[0].path.size(), 2u);
  EXPECT_EQ(s.grabs[0].path[0].frame, 20);
  EXPECT_TRUE((s.grabs[0].path[0].offset == hpcm::Vec3{0, -6, 0}));
  ASSERT_TRUE(s.grabs[1].centre.has_value());
  EXPECT_TRUE((*s.grabs[1].centre == hpcm::Int3{40, 12, 20}));
  EXPECT_EQ(s.grabs[1].radius, 2.5f);
  EXPECT_EQ(s.grabs[1].start, 100);
  EXPECT_EQ(s.grabs[1].release, 25);
  EXPECT_TRUE((s.grabs[1].path[1].offset == hpcm::Vec3{3.5f, 0.0f, -2.25f}));
}

TEST(ScenarioFile, RoundTrip) {
  const Scenario s = cfg::parse_scenario(kTwoGrabs, "two.toml");
  expect_scenario_eq(cfg::parse_scenario(cfg::scenario_to_toml(s), "rt.toml"), s);
  Scenario odd = s;
  odd.name = "quote \" backslash \\ tab\t";
  odd.grabs[1].path[0].offset = {0.1f, -1e-7f, 0.3333333f};
  odd.grabs[0].path.clear();
  expect_scenario_eq(cfg::parse_scenario(cfg::scenario_to_toml(odd), "rt.toml"), odd);
  const Scenario paper = Scenario::paper_protocol();
  expect_scenario_eq(cfg::parse_scenario(cfg::scenario_to_toml(paper), "paper.toml"), paper);
}

TEST(ScenarioFile, PaperShortcuts) {
  expect_scenario_eq(cfg::parse_scenario("paper = true\n", "p.toml"), Scenario::paper_protocol());
  expect_scenario_eq(cfg::parse_scenario("[paper]\n", "p.toml"), Scenario::paper_protocol());
  expect_scenario_eq(cfg::parse_scenario("[paper]\ndistance = 4\npull = 10\nhold = 5\nrecord = 60\n", "p.toml"),
                     Scenario::paper_protocol(4.0f, 10, 5, 60));
  expect_scenario_eq(cfg::parse_scenario("paper = { record = 200 }\n", "p.toml"), Scenario::paper_protocol(6.0f, 20, 10, 200));
  Scenario named = Scenario::paper_protocol();
  named.name = "mine";
  expect_scenario_eq(cfg::parse_scenario("paper = true\n[scenario]\nname = \"mine\"\n", "p.toml"), named);
}

TEST(ScenarioFile, Errors) {
  struct Case {
    std::string text, want;
  };
  const std::string grab = "[scenario]\nframes = 100\n[[grab]]\n";
  const std::vector<Case> cases = {
      {"", "scenario.frames is missing"},
      {"[scenario]\nname = \"x\"\n", "scenario.frames is missing"},
      {"[scenario]\nframes = 0\n", "scenario.frames = 0 is out of range [1, 10000000]"},
      {"[scenario]\nframes = 10.5\n", "scenario.frames must be an integer"},
      {"[scenario]\nframes = 10\nfps = 60\n", "unknown key 'scenario.fps'"},
      {"[scenario]\nframes = 10\n[grab]\nrelease = 3\n", "grab must be an array"},
      {grab + "start = 0\n", "grab[0].release is missing"},
      {grab + "release = 0\n", "grab[0].release = 0 is out of range [1, "},
      {grab + "release = 5\nstart = -1\n", "grab[0].start = -1 is out of range [0, 99]"},
      {grab + "release = 5\nstart = 100\n", "grab[0].start = 100 is out of range [0, 99]"},
      {grab + "release = 5\nradius = -1\n", "grab[0].radius = -1.0 is out of range [0, 64]"},
      {grab + "release = 5\nradius = nan\n", "grab[0].radius = nan is not a finite number"},
      {grab + "release = 5\ncentre = \"middle\"\n", "grab[0].centre = \"middle\" must be \"auto\" or [x, y, z]"},
      {grab + "release = 5\ncentre = [1, 2]\n", "grab[0].centre must be \"auto\" or an array of 3"},
      {grab + "release = 5\ncentre = [1, -2, 3]\n", "grab[0].centre[1] = -2 must be >= 0"},
      {grab + "release = 5\ncentre = [1, 2.5, 3]\n", "grab[0].centre[1] must be an integer"},
      {grab + "release = 5\nkeyframes = [[10, 0, -1, 0], [10, 0, -2, 0]]\n",
       "grab[0].keyframes[1] frame 10 must be greater than the previous keyframe's frame 10"},
      {grab + "release = 5\nkeyframes = [[10, 0, -1, 0], [5, 0, -2, 0]]\n", "strictly increase"},
      {grab + "release = 5\nkeyframes = [[-1, 0, -1, 0]]\n", "grab[0].keyframes[0] frame = -1 is out of range [0, "},
      {grab + "release = 5\nkeyframes = [[1.5, 0, -1, 0]]\n", "grab[0].keyframes[0][0] (frame) must be an integer"},
      {grab + "release = 5\nkeyframes = [[1, 0, -1]]\n", "grab[0].keyframes[0] must be [frame, dx, dy, dz]"},
      {grab + "release = 5\nkeyframes = [[1, 0, inf, 0]]\n", "grab[0].keyframes[0][2] (dy) = inf is not a finite number"},
      {grab + "release = 5\nkeyframes = [[1, 0, \"up\", 0]]\n", "(dy) must be a number"},
      {grab + "release = 5\nkeyframes = [1, 0, 0, 0]\n", "grab[0].keyframes[0] must be [frame, dx, dy, dz]"},
      {grab + "release = 5\nhold = 3\n", "unknown key 'grab[0].hold'"},
      {grab + "start = 10\nrelease = 20\n[[grab]]\nstart = 25\nrelease = 5\n",
       "grab[1].start = 25 overlaps grab[0], which is held until frame 30"},
      {"paper = true\n[[grab]]\nrelease = 5\n", "paper cannot be combined with [[grab]]"},
      {"paper = true\n[scenario]\nframes = 10\n", "scenario.frames cannot be combined with paper"},
      {"paper = false\n", "paper = false"},
      {"paper = 1\n", "paper must be true or a table"},
      {"[paper]\npull = 0\n", "paper.pull = 0 is out of range [1, "},
      {"[paper]\nhold = -1\n", "paper.hold = -1 is out of range [0, "},
      {"[paper]\nrecord = 0\n", "paper.record = 0 is out of range [1, "},
      {"[paper]\ndistance = -1\n", "paper.distance = -1.0 is out of range [0, 1000]"},
      {"[paper]\nfrom = 3\n", "unknown key 'paper.from'"},
      {"[scenario]\nframes = 10\nscenario = 3\n", "unknown key 'scenario.scenario'"},
      {"[scenario\nframes = 10\n", "TOML syntax error"},
      // Millimetres beside lattice units: exactly one form per grab radius and per keyframe.
      {grab + "release = 5\nradius = 2\nradius_mm = 5\n",
       "grab[0] gives both radius and radius_mm: give one (radius in lattice units, radius_mm in millimetres) (line 6)"},
      {grab + "release = 5\nradius_mm = -1\n", "grab[0].radius_mm = -1 is out of range: > 0 mm and at most 64 lattice units"},
      {grab + "release = 5\nradius_mm = nan\n", "grab[0].radius_mm = nan is out of range: > 0 mm and at most 64 lattice units"},
      {grab + "release = 5\nradius_mm = 0\n", "grab[0].radius_mm = 0 is out of range: > 0 mm"},
      {grab + "release = 5\nradius_mm = \"5mm\"\n", "grab[0].radius_mm must be a number"},
      {grab + "release = 5\nkeyframes = [{ frame = 10, offset = [0, -1, 0], offset_mm = [0, -5, 0] }]\n",
       "grab[0].keyframes[0] gives both offset and offset_mm: give one (offset in lattice units, offset_mm in millimetres) "
       "(line 5)"},
      {grab + "release = 5\nkeyframes = [{ frame = 10 }]\n",
       "grab[0].keyframes[0] needs offset = [dx, dy, dz] (lattice units) or offset_mm = [dx, dy, dz] (millimetres)"},
      {grab + "release = 5\nkeyframes = [{ offset_mm = [0, -5, 0] }]\n", "grab[0].keyframes[0].frame is missing"},
      {grab + "release = 5\nkeyframes = [{ frame = 10, offset_mm = [0, -5] }]\n",
       "grab[0].keyframes[0].offset_mm must be [dx, dy, dz]"},
      {grab + "release = 5\nkeyframes = [{ frame = 10, offset_mm = [0, nan, 0] }]\n",
       "grab[0].keyframes[0].offset_mm[1] = nan is not a finite number"},
      {grab + "release = 5\nkeyframes = [{ frame = 10, offset = [0, -20000, 0] }]\n",
       "grab[0].keyframes[0].offset[1] = -20000.0 is out of range [-10000, 10000] lattice units"},
      {grab + "release = 5\nkeyframes = [{ frame = 10, offset_mm = [0, -5, 0], speed = 2 }]\n",
       "unknown key 'grab[0].keyframes[0].speed'"},
      {grab + "release = 5\nkeyframes = [{ frame = -1, offset_mm = [0, -5, 0] }]\n",
       "grab[0].keyframes[0] frame = -1 is out of range [0, "},
  };
  for (const auto& c : cases) {
    const std::string msg = scenario_error_of(c.text);
    ASSERT_FALSE(msg.empty()) << "accepted:\n" << c.text;
    EXPECT_EQ(msg.rfind("scn.toml: ", 0), 0u) << msg;
    EXPECT_CONTAINS(msg, c.want);
  }
}

// Keyframes and grab radii in millimetres beside lattice units; kept as written (converted with
// the lattice spacing only when played) and written back in the same form.
TEST(ScenarioFile, MillimetreForms) {
  const Scenario s = cfg::parse_scenario(R"(
[scenario]
frames = 60
[[grab]]
radius_mm = 7.5
release = 40
keyframes = [
  [5, 0, -1, 0],
  { frame = 10, offset = [0, -2, 0] },
  { frame = 20, offset_mm = [1.5, -18, 0.25] },
]
)", "mm.toml");
  ASSERT_EQ(s.grabs.size(), 1u);
  const hpcm::GrabAction& g = s.grabs[0];
  EXPECT_EQ(g.radius_units, hpcm::Units::mm);
  EXPECT_FLOAT_EQ(g.radius, 7.5f);
  ASSERT_EQ(g.path.size(), 3u);
  EXPECT_EQ(g.path[0].units, hpcm::Units::lattice);
  EXPECT_EQ(g.path[1].units, hpcm::Units::lattice);
  EXPECT_TRUE(g.path[1].offset == (hpcm::Vec3{0, -2, 0}));
  EXPECT_EQ(g.path[2].frame, 20);
  EXPECT_EQ(g.path[2].units, hpcm::Units::mm);
  EXPECT_TRUE(g.path[2].offset == (hpcm::Vec3{1.5f, -18, 0.25f}));
  const std::string text = cfg::scenario_to_toml(s);
  EXPECT_CONTAINS(text, "radius_mm = 7.5");
  EXPECT_CONTAINS(text, "{ frame = 20, offset_mm = [1.5, -18.0, 0.25] }");
  expect_scenario_eq(cfg::parse_scenario(text, "rt.toml"), s);
  // A radius in lattice units stays one.
  const Scenario lattice = cfg::parse_scenario("[scenario]\nframes = 5\n[[grab]]\nradius = 2\nrelease = 3\n", "l.toml");
  EXPECT_EQ(lattice.grabs[0].radius_units, hpcm::Units::lattice);
}

TEST(ScenarioFile, NoGrabsIsAnIdleScenario) {
  const Scenario s = cfg::parse_scenario("[scenario]\nframes = 5\n", "idle.toml");
  EXPECT_EQ(s.frames, 5);
  EXPECT_TRUE(s.grabs.empty());
  EXPECT_EQ(s.name, Scenario{}.name);
}

TEST(ScenarioFile, ExampleScenarioFilesParse) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(HPCM_SOURCE_DIR) / "examples";
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("params_", 0) == 0 || e.path().extension() != ".toml") continue;
    EXPECT_NO_THROW(cfg::load_scenario(e.path().string())) << name;
    ++n;
  }
  EXPECT_GE(n, 2) << "expected examples/paper_protocol.toml and examples/two_grabs.toml";
  expect_scenario_eq(cfg::load_scenario((dir / "paper_protocol.toml").string()), Scenario::paper_protocol());
}

TEST(ScenarioFile, MissingFile) {
  try {
    cfg::load_scenario("/nonexistent/dir/s.toml");
    ADD_FAILURE() << "opened a missing file";
  } catch (const hpcm::Error& e) {
    EXPECT_CONTAINS(e.what(), "/nonexistent/dir/s.toml: cannot open");
  }
}
