// The viewer's parameter panel: every parameter of the table is there (relax_omega and the
// sleep settings included), labelled with its range, and every slider stays inside it.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "param_panel.hpp"
#include "param_test_util.hpp"

using namespace hpcm;
using hpcm::viewer::panel_params;

namespace {

/// The message of check_param_ranges with every number of the entry set to v, or "".
std::string error_at(const ParamSpec& s, double v) {
  Params p;
  test::set_all(s, p, v);
  return test::range_error(p);
}

}  // namespace

TEST(ParamPanel, ShowsEveryParameterOfTheTable) {
  std::set<std::string> shown;
  for (const char* section : {"tissue", "material", "solver", "dynamics"})
    for (const auto& w : panel_params(section)) shown.insert(w.spec->key);
  for (const ParamSpec& s : param_table()) EXPECT_TRUE(shown.count(s.key)) << s.key << " is not in the panel";
  for (const char* k : {"solver.relax_omega", "solver.sleep", "dynamics.sleep_speed"}) EXPECT_TRUE(shown.count(k)) << k;
}

TEST(ParamPanel, LabelsGiveTheRangeAndSlidersStayInsideIt) {
  for (const char* section : {"tissue", "material", "solver", "dynamics"})
    for (const auto& w : panel_params(section)) {
      const ParamSpec& s = *w.spec;
      EXPECT_EQ(w.label.rfind(s.name(), 0), 0u) << w.label;
      EXPECT_NE(w.tooltip.find(s.help), std::string::npos) << s.key;
      const bool slider = s.type == ParamType::Real || s.type == ParamType::PerClass || s.type == ParamType::PointField ||
                          (s.type == ParamType::Integer && s.allowed.empty());
      if (!slider) continue;
      EXPECT_NE(w.label.find(range_text(s)), std::string::npos) << w.label;
      EXPECT_TRUE(std::isfinite(w.lo) && std::isfinite(w.hi) && w.lo < w.hi) << s.key << " [" << w.lo << ", " << w.hi << "]";
      EXPECT_EQ(error_at(s, w.lo), "") << s.key << ": slider start";
      EXPECT_EQ(error_at(s, w.hi), "") << s.key << ": slider end";
    }
}
