#include "hpcm/param_table.hpp"

#include <cmath>
#include <limits>
#include <sstream>

namespace hpcm {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr ParamRange kFinite{-kInf, kInf};

/// A spec with its key, type and range; every other member at its default.
ParamSpec spec(std::string key, ParamType type, ParamRange range = {0, 0}) {
  ParamSpec s;
  s.key = std::move(key);
  s.type = type;
  s.range = range;
  return s;
}

ParamSpec real(std::string key, float& (*field)(Params&), ParamRange range, std::string unit, std::string help,
               SliderHint slider = {0, 0}) {
  ParamSpec s = spec(std::move(key), ParamType::Real, range);
  s.real = field, s.unit = std::move(unit), s.help = std::move(help), s.slider = slider;
  return s;
}

ParamSpec integer(std::string key, int& (*field)(Params&), ParamRange range, std::string help, SliderHint slider = {0, 0}) {
  ParamSpec s = spec(std::move(key), ParamType::Integer, range);
  s.integer = field, s.help = std::move(help), s.slider = slider;
  return s;
}

ParamSpec flag(std::string key, bool& (*field)(Params&), std::string help) {
  ParamSpec s = spec(std::move(key), ParamType::Flag);
  s.flag = field, s.help = std::move(help);
  return s;
}

ParamSpec per_class(std::string key, PerTissue& (*field)(Params&), ParamRange range, std::string help,
                    SliderHint slider = {0, 0}) {
  ParamSpec s = spec(std::move(key), ParamType::PerClass, range);
  s.per_class = field, s.help = std::move(help), s.slider = slider;
  return s;
}

ParamSpec point_field(std::string key, float MaterialPoint::*field, ParamRange range, std::string unit, std::string help,
                      SliderHint slider) {
  ParamSpec s = spec(std::move(key), ParamType::PointField, range);
  s.point_field = field, s.unit = std::move(unit), s.help = std::move(help), s.slider = slider;
  return s;
}

std::string num(double v) { return format_number(v); }

std::vector<ParamSpec> make_table() {
  constexpr ParamRange unit_interval{0, 1};
  const std::string lu = "lattice units", per_frame = "lattice units / frame";
  std::vector<ParamSpec> t;

  // [tissue]
  t.push_back(real("tissue.t1", [](Params& p) -> float& { return p.tissue.t1; }, kFinite, "HU",
                   "air | skin_fat threshold; t1 < t2 < t3 (strictly increasing)", {-2000, 4000}));
  t.push_back(real("tissue.t2", [](Params& p) -> float& { return p.tissue.t2; }, kFinite, "HU",
                   "skin_fat | muscle_organ threshold", {-2000, 4000}));
  t.push_back(real("tissue.t3", [](Params& p) -> float& { return p.tissue.t3; }, kFinite, "HU",
                   "muscle_organ | bone threshold", {-2000, 4000}));

  // [material]
  {
    ParamSpec s = spec("material.points", ParamType::Points);
    s.points = [](Params& p) -> std::vector<MaterialPoint>& { return p.material.points; };
    s.help = "control points { hu, tau, w }: at least 2, hu strictly increasing; giving points replaces the whole list";
    t.push_back(std::move(s));
  }
  t.push_back(point_field("material.points[].hu", &MaterialPoint::hu, kFinite, "HU", "the point's HU", {-3000, 5000}));
  t.push_back(point_field("material.points[].tau", &MaterialPoint::tau, {0, 1, true}, lu,
                          "tolerance: a link's axial spacing stays in [1 - 0.8 tau, 1 + tau], its shear within tau",
                          {1e-4, 1, true}));
  {
    ParamSpec w = point_field("material.points[].w", &MaterialPoint::w, {kMinLinkPenalty, kMaxLinkPenalty}, "",
                              "propagation time penalty of a link", {kMinLinkPenalty, kMaxLinkPenalty, true});
    w.out_of_range_note =
        " (the propagation counts arrival times in steps of the smallest w: their number must fit 64 bits)";
    t.push_back(std::move(w));
  }

  // [solver]
  t.push_back(real("solver.grab_radius", [](Params& p) -> float& { return p.solver.grab_radius; }, {0, 64, true}, lu,
                   "elements this close to the grab centre follow the tool", {0.1, 64, true}));
  {
    ParamSpec s = integer("solver.brick_size", [](Params& p) -> int& { return p.solver.brick_size; }, {4, 16},
                          "edge of the bricks of sparse work (CPU)");
    s.allowed = {4, 8, 16};
    t.push_back(std::move(s));
  }
  t.push_back(integer("solver.relax_sweeps", [](Params& p) -> int& { return p.solver.relax_sweeps; }, {0, 256},
                      "relaxation sweeps K per frame (early exit below the threshold); with the velocity layer on, "
                      "fewer sweeps lower the stable inertia gain (stability rule; its error names the fewest sweeps that would do)"));
  t.push_back(real("solver.relax_threshold", [](Params& p) -> float& { return p.solver.relax_threshold; }, {0, 0.999}, lu,
                   "smaller relaxation corrections are skipped: decides how far a pull reaches (docs/tuning.md, Reach "
                   "and settling); with the velocity layer on, dynamics.dead_zone must be at least " + num(kDeadZonePerThreshold) + " times it",
                   {0, 0.999, true}));
  t.push_back(real("solver.relax_slack", [](Params& p) -> float& { return p.solver.relax_slack; }, {0, 1e6}, lu,
                   "within this distance of rest, relaxation corrections below solver.relax_threshold are skipped "
                   "(ChainMail's slack); farther from rest every correction is applied, so released tissue returns to "
                   "within it and tissue carried past rest is pulled back (docs/solver.md, Reach and slack); 0 applies "
                   "every correction everywhere, 1e6 skips small corrections everywhere (the rule before this setting)",
                   {0, 4, false}));
  t.push_back(real("solver.relax_omega", [](Params& p) -> float& { return p.solver.relax_omega; }, {1, 1.95}, "",
                   "over-relaxation of each relaxation step (1 = plain Gauss-Seidel, the paper's rule); enters the "
                   "stability rule"));
  {
    ParamSpec s = spec("solver.anchors", ParamType::Choice);
    s.choices = {"none", "bone", "border"};
    s.choice_name = [](const Params& p) -> std::string { return anchor_mode_name(p.solver.anchors); };
    s.set_choice = [](Params& p, const std::string& v) { p.solver.anchors = parse_anchor_mode(v, "solver.anchors"); };
    s.help = "elements held FIXED every frame";
    t.push_back(std::move(s));
  }
  t.push_back(integer("solver.max_propagation_sweeps", [](Params& p) -> int& { return p.solver.max_propagation_sweeps; },
                      {1, 10000000}, "safety cap on propagation sweeps per frame", {1, 10000000, true}));
  t.push_back(flag("solver.grab_slip", [](Params& p) -> bool& { return p.solver.grab_slip; },
                   "elements within the grab radius, other than the centre, that touch an anchored element outside the "
                   "grab slip from the tool: tissue bound to bone or the table does not follow it (docs/solver.md, The "
                   "tool limit); false holds every element within the radius"));
  t.push_back(flag("solver.sleep", [](Params& p) -> bool& { return p.solver.sleep; },
                   "bricks (brick_size^3 elements) where nothing moves are skipped until the wave, a moving neighbour or "
                   "the tool wakes them; false keeps every brick awake every frame (the exact reference, for measuring "
                   "what sleeping changes)"));

  // [dynamics]
  {
    ParamSpec s = spec("dynamics.mode", ParamType::Choice);
    s.choices = {"none", "simple", "viscoelastic"};
    s.choice_name = [](const Params& p) -> std::string { return damping_mode_name(p.dynamics.mode); };
    s.set_choice = [](Params& p, const std::string& v) { p.dynamics.mode = parse_damping_mode(v, "dynamics.mode"); };
    s.help = "damping of the velocity layer: condition A, B or C (\"A\", \"B\", \"C\" are accepted too)";
    t.push_back(std::move(s));
  }
  t.push_back(real("dynamics.alpha", [](Params& p) -> float& { return p.dynamics.alpha; }, unit_interval, "",
                   "simple damping V <- alpha V + s dX; at most " + num(kMaxSettlingAlpha) + " under simple (stability rule)"));
  t.push_back(real("dynamics.b0", [](Params& p) -> float& { return p.dynamics.b0; }, unit_interval, "",
                   "viscoelastic V <- (V + s dX) / (1 + b0 + b1 |X - X0|); at least " + num(kMinSettlingB0) +
                       " under viscoelastic (stability rule)"));
  t.push_back(per_class("dynamics.b1", [](Params& p) -> PerTissue& { return p.dynamics.b1; }, unit_interval,
                        "displacement-dependent viscoelastic damping per class"));
  t.push_back(per_class("dynamics.inverse_mass", [](Params& p) -> PerTissue& { return p.dynamics.inverse_mass; }, {0, 1e6},
                        "per class; 0 = no dynamics for that class; at least one class > 0", {0, 1e6, true}));
  t.push_back(real("dynamics.s_min", [](Params& p) -> float& { return p.dynamics.s_min; }, unit_interval, "",
                   "response scale s = clamp(inverse_mass / max inverse_mass, s_min, s_max); s_min <= s_max"));
  t.push_back(real("dynamics.s_max", [](Params& p) -> float& { return p.dynamics.s_max; }, unit_interval, "",
                   "upper clamp of the response scale; s_min <= s_max"));
  t.push_back(real("dynamics.dead_zone", [](Params& p) -> float& { return p.dynamics.dead_zone; }, {0, 0.999}, lu,
                   "ChainMail corrections |dX| below this count as 0 (stops drift, and the relay of the relaxation's "
                   "threshold: docs/velocity_layer.md); under simple and viscoelastic at least " +
                       num(kMinSettlingDeadZone) + " and at least " + num(kDeadZonePerThreshold) +
                       " * solver.relax_threshold (stability rule)",
                   {0, 0.999, true}));
  t.push_back(real("dynamics.v_max", [](Params& p) -> float& { return p.dynamics.v_max; }, {0, 10, true}, per_frame,
                   "velocity magnitude clamp", {0.001, 10, true}));
  t.push_back(real("dynamics.beta", [](Params& p) -> float& { return p.dynamics.beta; }, {0, 2}, "",
                   "global inertia gain X <- X+ + beta rho V; beta * rho * s is bounded by the stability rule"));
  t.push_back(per_class("dynamics.rho", [](Params& p) -> PerTissue& { return p.dynamics.rho; }, {0, 2},
                        "per-class position gain (stability rule)"));
  t.push_back(real("dynamics.margin", [](Params& p) -> float& { return p.dynamics.margin; }, {0, 64}, lu,
                   "positions stay in [-margin, N - 1 + margin]"));
  t.push_back(real("dynamics.sleep_speed", [](Params& p) -> float& { return p.dynamics.sleep_speed; }, {0, 0.01}, per_frame,
                   "with solver.sleep: a brick the ChainMail stage did not touch, whose velocities all stayed below "
                   "this, comes to rest (velocities 0) and sleeps",
                   {0, 0.01, true}));
  return t;
}

// Shared by the numeric types: "<key> = <v> is out of range [lo, hi]" with lo, hi and v as T
// prints them (the message form Params::validate has always used).
template <class T>
void check_number(const ParamSpec& s, const std::string& key, T v) {
  const bool finite_only = std::isinf(s.range.lo) && std::isinf(s.range.hi);
  if (finite_only) {
    if (std::isfinite(static_cast<double>(v))) return;
    std::ostringstream m;
    m << key << " = " << v << " must be a finite " << (s.unit.empty() ? "" : s.unit + " ") << "value";
    throw Error(m.str());
  }
  if (!s.allowed.empty()) {
    for (int a : s.allowed)
      if (static_cast<double>(v) == a) return;
    std::ostringstream m;
    m << key << " = " << v << " must be ";
    for (std::size_t i = 0; i < s.allowed.size(); ++i)
      m << (i == 0 ? "" : i + 1 == s.allowed.size() ? " or " : ", ") << s.allowed[i];
    throw Error(m.str());
  }
  const T lo = static_cast<T>(s.range.lo), hi = static_cast<T>(s.range.hi);
  const bool ok = std::isfinite(static_cast<double>(v)) && (s.range.lo_open ? v > lo : v >= lo) &&
                  (s.range.hi_open ? v < hi : v <= hi);
  if (ok) return;
  std::ostringstream m;
  m << key << " = " << v << " is out of range " << (s.range.lo_open ? "(" : "[") << lo << ", " << hi
    << (s.range.hi_open ? ")" : "]") << s.out_of_range_note;
  throw Error(m.str());
}

}  // namespace

std::string ParamSpec::name() const {
  const auto dot = key.find('.');
  const auto bracket = key.find("[].");
  return bracket != std::string::npos ? key.substr(bracket + 3) : key.substr(dot + 1);
}

std::string ParamSpec::section() const { return key.substr(0, key.find('.')); }

const std::vector<ParamSpec>& param_table() {
  static const std::vector<ParamSpec> table = make_table();
  return table;
}

const ParamSpec* find_param(const std::string& key) {
  for (const ParamSpec& s : param_table())
    if (s.key == key) return &s;
  return nullptr;
}

std::string format_number(double v) {
  if (v == std::floor(v) && std::abs(v) < 1e5) return std::to_string(static_cast<long long>(v));
  std::ostringstream o;
  o << static_cast<float>(v);  // at most 6 significant digits, as the values are written
  std::string s = o.str();
  // 1e-06 -> 1e-6, 1e+06 -> 1e6
  const auto e = s.find('e');
  if (e != std::string::npos) {
    std::string mant = s.substr(0, e), exp = s.substr(e + 1);
    const bool neg = exp[0] == '-';
    exp = exp.substr(exp[0] == '-' || exp[0] == '+' ? 1 : 0);
    while (exp.size() > 1 && exp[0] == '0') exp.erase(0, 1);
    s = mant + "e" + (neg ? "-" : "") + exp;
  }
  return s;
}

std::string range_text(const ParamSpec& s) {
  auto join = [](const std::vector<std::string>& v, bool quote) {
    std::string out;
    for (std::size_t i = 0; i < v.size(); ++i) out += (i ? " | " : "") + (quote ? "\"" + v[i] + "\"" : v[i]);
    return out;
  };
  switch (s.type) {
    case ParamType::Flag: return "true | false";
    case ParamType::Choice: return join(s.choices, true);
    case ParamType::Points: return "at least 2 points";
    default: break;
  }
  if (!s.allowed.empty()) {
    std::vector<std::string> v;
    for (int a : s.allowed) v.push_back(std::to_string(a));
    return join(v, false);
  }
  if (std::isinf(s.range.lo) && std::isinf(s.range.hi)) return "finite";
  return (s.range.lo_open ? "(" : "[") + format_number(s.range.lo) + ", " + format_number(s.range.hi) +
         (s.range.hi_open ? ")" : "]");
}

std::string default_text(const ParamSpec& s) {
  Params d;  // the defaults are the default-constructed Params, never retyped here
  switch (s.type) {
    case ParamType::Real: return format_number(s.real(d));
    case ParamType::Integer: return std::to_string(s.integer(d));
    case ParamType::Flag: return s.flag(d) ? "true" : "false";
    case ParamType::Choice: return "\"" + s.choice_name(d) + "\"";
    case ParamType::PerClass: {
      const PerTissue& v = s.per_class(d);
      bool same = true;
      for (float x : v) same = same && x == v[0];
      if (same) return format_number(v[0]) + " each";
      std::string out;
      for (int c = 0; c < kTissueCount; ++c)
        out += std::string(c ? ", " : "") + tissue_name(c) + " " + format_number(v[static_cast<std::size_t>(c)]);
      return out;
    }
    case ParamType::Points: return std::to_string(s.points(d).size()) + " points";
    case ParamType::PointField: {
      std::string out;
      const auto& pts = d.material.points;
      for (std::size_t i = 0; i < pts.size(); ++i) out += (i ? ", " : "") + format_number(pts[i].*s.point_field);
      return out;
    }
  }
  return "";
}

namespace {
std::string md_cell(const std::string& text) {
  std::string out;
  for (char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}
}  // namespace

std::string param_table_markdown() {
  std::string out;
  std::string section;
  auto close = [&] {
    if (!section.empty()) out += "<!-- END generated parameter table [" + section + "] -->\n";
  };
  for (const ParamSpec& s : param_table()) {
    if (s.section() != section) {
      close();
      if (!section.empty()) out += "\n";
      section = s.section();
      out += "<!-- BEGIN generated parameter table [" + section + "]: do not edit, see \"Regenerating\" below -->\n";
      out += "| key | default | valid | unit | meaning |\n|---|---|---|---|---|\n";
    }
    const std::string key = s.type == ParamType::PointField ? "points[]." + s.name() : s.name();
    out += "| `" + key + "` | " + md_cell(default_text(s)) + " | " + md_cell(range_text(s)) +
           (s.type == ParamType::PerClass ? " each" : "") + " | " + s.unit + " | " + md_cell(s.help) + " |\n";
  }
  close();
  return out;
}

void check_param_ranges(const Params& p) {
  Params& q = const_cast<Params&>(p);  // the accessors give references; nothing is written here
  for (const ParamSpec& s : param_table()) {
    switch (s.type) {
      case ParamType::Real: check_number(s, s.key, s.real(q)); break;
      case ParamType::Integer: check_number(s, s.key, s.integer(q)); break;
      case ParamType::PerClass:
        for (int c = 0; c < kTissueCount; ++c)
          check_number(s, s.key + "." + tissue_name(c), s.per_class(q)[static_cast<std::size_t>(c)]);
        break;
      case ParamType::PointField: {
        const auto& pts = q.material.points;
        for (std::size_t i = 0; i < pts.size(); ++i)
          check_number(s, "material.points[" + std::to_string(i) + "]." + s.name(), pts[i].*s.point_field);
        break;
      }
      case ParamType::Flag:
      case ParamType::Choice:
      case ParamType::Points: break;  // any value of the type is valid (Points: a named rule)
    }
  }
}

}  // namespace hpcm
