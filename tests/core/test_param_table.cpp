// The parameter table: every entry reaches its own field, its default is the default Params',
// and validation follows its range at each bound.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "hpcm/param_table.hpp"
#include "param_test_util.hpp"

using namespace hpcm;
using hpcm::test::range_error;
using hpcm::test::set_all;

namespace {

bool numeric(const ParamSpec& s) {
  return s.type == ParamType::Real || s.type == ParamType::Integer || s.type == ParamType::PerClass ||
         s.type == ParamType::PointField;
}

/// The value next to `bound` on the outside of the range (float or int steps).
double outside(const ParamSpec& s, double bound, bool below) {
  if (s.type == ParamType::Integer) return below ? bound - 1 : bound + 1;
  const float b = static_cast<float>(bound);
  return std::nextafter(b, below ? -INFINITY : INFINITY);
}

}  // namespace

TEST(ParamTable, KeysAreUniqueAndSectioned) {
  std::set<std::string> keys;
  const std::set<std::string> sections{"tissue", "material", "solver", "dynamics"};
  for (const ParamSpec& s : param_table()) {
    EXPECT_TRUE(keys.insert(s.key).second) << "duplicate " << s.key;
    EXPECT_TRUE(sections.count(s.section())) << s.key;
    EXPECT_FALSE(s.help.empty()) << s.key;
  }
  for (const char* k : {"tissue.t1", "material.points", "material.points[].tau", "solver.relax_omega", "solver.sleep",
                        "dynamics.sleep_speed", "dynamics.inverse_mass", "dynamics.mode", "solver.anchors"})
    EXPECT_NE(find_param(k), nullptr) << k;
  EXPECT_EQ(find_param("dynamics.alpah"), nullptr);
}

// Each accessor writes its own field and no other entry's: changing one entry leaves every
// other entry's value as it was, and the Params differs from the default.
TEST(ParamTable, EachEntryReachesItsOwnField) {
  const Params d;
  for (const ParamSpec& s : param_table()) {
    Params p;
    switch (s.type) {
      case ParamType::Real: s.real(p) += 0.5f; break;
      case ParamType::Integer: s.integer(p) += 1; break;
      case ParamType::Flag: s.flag(p) = !s.flag(p); break;
      case ParamType::Choice: s.set_choice(p, s.choices.back() == s.choice_name(p) ? s.choices.front() : s.choices.back()); break;
      case ParamType::PerClass: s.per_class(p)[1] += 0.5f; break;
      case ParamType::Points: s.points(p).push_back(s.points(p).back()); break;
      case ParamType::PointField: p.material.points[1].*s.point_field += 0.5f; break;
    }
    EXPECT_FALSE(p == d) << s.key << " changes nothing";
    for (const ParamSpec& o : param_table()) {
      if (&o == &s || o.type == ParamType::Points || s.type == ParamType::Points) continue;
      if (o.type == ParamType::PointField && s.type == ParamType::PointField) {
        if (o.point_field != s.point_field) EXPECT_EQ(p.material.points[1].*o.point_field, d.material.points[1].*o.point_field) << s.key << " -> " << o.key;
        continue;
      }
      Params q = p;
      Params& dd = const_cast<Params&>(d);
      switch (o.type) {
        case ParamType::Real: EXPECT_EQ(o.real(q), o.real(dd)) << s.key << " -> " << o.key; break;
        case ParamType::Integer: EXPECT_EQ(o.integer(q), o.integer(dd)) << s.key << " -> " << o.key; break;
        case ParamType::Flag: EXPECT_EQ(o.flag(q), o.flag(dd)) << s.key << " -> " << o.key; break;
        case ParamType::Choice: EXPECT_EQ(o.choice_name(q), o.choice_name(d)) << s.key << " -> " << o.key; break;
        case ParamType::PerClass: EXPECT_EQ(o.per_class(q), o.per_class(dd)) << s.key << " -> " << o.key; break;
        default: break;
      }
    }
  }
}

TEST(ParamTable, DefaultsAreTheDefaultParams) {
  EXPECT_EQ(default_text(*find_param("dynamics.alpha")), "0.98");
  EXPECT_EQ(default_text(*find_param("solver.relax_omega")), "1.85");
  EXPECT_EQ(default_text(*find_param("solver.brick_size")), "8");
  EXPECT_EQ(default_text(*find_param("solver.sleep")), "true");
  EXPECT_EQ(default_text(*find_param("solver.anchors")), "\"bone\"");
  EXPECT_EQ(default_text(*find_param("dynamics.sleep_speed")), "1e-7");
  EXPECT_EQ(default_text(*find_param("dynamics.rho")), "1 each");
  EXPECT_EQ(default_text(*find_param("dynamics.inverse_mass")), "air 1, skin_fat 1, muscle_organ 0.15, bone 0");
  EXPECT_EQ(default_text(*find_param("material.points[].tau")), "0.5, 0.35, 0.22, 0.005");
  EXPECT_EQ(range_error(Params{}), "");
}

TEST(ParamTable, RangeTexts) {
  EXPECT_EQ(range_text(*find_param("solver.grab_radius")), "(0, 64]");
  EXPECT_EQ(range_text(*find_param("solver.brick_size")), "4 | 8 | 16");
  EXPECT_EQ(range_text(*find_param("solver.max_propagation_sweeps")), "[1, 1e7]");
  EXPECT_EQ(range_text(*find_param("dynamics.inverse_mass")), "[0, 1e6]");
  EXPECT_EQ(range_text(*find_param("material.points[].w")), "[1e-6, 100]");
  EXPECT_EQ(range_text(*find_param("dynamics.mode")), "\"none\" | \"simple\" | \"viscoelastic\"");
  EXPECT_EQ(range_text(*find_param("tissue.t1")), "finite");
  EXPECT_EQ(format_number(0.999), "0.999");
  EXPECT_EQ(format_number(1e-7f), "1e-7");
  EXPECT_EQ(format_number(-1000), "-1000");
  EXPECT_EQ(format_number(100000), "100000");
  EXPECT_EQ(format_number(2.5e6), "2.5e6");
}

// At every finite bound: inside is accepted, the next value outside is rejected with the
// message naming the key and the range; NaN is rejected for every real-valued entry.
TEST(ParamTable, ValidationFollowsEachRange) {
  int checked = 0;
  for (const ParamSpec& s : param_table()) {
    if (!numeric(s) || !s.allowed.empty()) continue;
    const std::string key = s.type == ParamType::PerClass     ? s.key + ".air"
                            : s.type == ParamType::PointField ? "material.points[0]." + s.name()
                                                              : s.key;
    for (const bool low : {true, false}) {
      const double bound = low ? s.range.lo : s.range.hi;
      if (std::isinf(bound)) continue;
      const bool open = low ? s.range.lo_open : s.range.hi_open;
      Params p;
      set_all(s, p, bound);
      const std::string at = range_error(p);
      if (open) {
        EXPECT_NE(at.find(key + " = "), std::string::npos) << s.key << " accepted its open bound: " << at;
      } else {
        EXPECT_EQ(at, "") << s.key << " rejected its bound " << bound;
        set_all(s, p, outside(s, bound, low));
        const std::string m = range_error(p);
        EXPECT_EQ(m.rfind(key + " = ", 0), 0u) << s.key << ": " << m;
        EXPECT_NE(m.find("is out of range"), std::string::npos) << m;
      }
      ++checked;
    }
    if (s.type != ParamType::Integer) {
      Params p;
      set_all(s, p, std::numeric_limits<double>::quiet_NaN());
      EXPECT_EQ(range_error(p).rfind(key + " = nan", 0), 0u) << range_error(p);
    }
  }
  EXPECT_GE(checked, 30);
  Params p;
  p.solver.brick_size = 6;
  EXPECT_EQ(range_error(p), "solver.brick_size = 6 must be 4, 8 or 16");
  p = Params{};
  p.material.points[2].w = 9e-7f;
  EXPECT_EQ(range_error(p),
            "material.points[2].w = 9e-07 is out of range [1e-06, 100] (the propagation counts arrival times in steps "
            "of the smallest w: their number must fit 64 bits)");
}

TEST(ParamTable, MarkdownHasEveryKeyBetweenFences) {
  const std::string md = param_table_markdown();
  for (const ParamSpec& s : param_table()) {
    const std::string key = s.type == ParamType::PointField ? "points[]." + s.name() : s.name();
    EXPECT_NE(md.find("| `" + key + "` | "), std::string::npos) << s.key;
  }
  for (const char* section : {"tissue", "material", "solver", "dynamics"}) {
    EXPECT_NE(md.find(std::string("<!-- BEGIN generated parameter table [") + section + "]"), std::string::npos);
    EXPECT_NE(md.find(std::string("<!-- END generated parameter table [") + section + "] -->"), std::string::npos);
  }
}
