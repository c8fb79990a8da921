// Parameter files (TOML): every field of hpcm::Params, strict reading, exact round trip.
#include <algorithm>
#include <fstream>
#include <sstream>

#include "toml_util.hpp"
#include "hpcm/config.hpp"
#include "hpcm/param_table.hpp"

namespace hpcm::config {

using detail::Ctx;
using detail::fail;
using detail::fmt_float;
using detail::Section;

namespace {

// ------------------------------------------------------------------------------------------
// Reading

/// Per-class value: a table {air, skin_fat, muscle_organ, bone} (missing classes keep their
/// value) or a single number for every class.
void read_per_tissue(Section& s, std::string_view key, PerTissue& out) {
  const toml::node* n = s.get(key);
  if (!n) return;
  const std::string path = s.path_of(key);
  if (n->is_number()) {
    const float v = detail::to_float(s.ctx(), *n, path);
    out.fill(v);
    return;
  }
  const toml::table* t = n->as_table();
  if (!t)
    fail(s.ctx(), n, path + " must be a table { air = ..., skin_fat = ..., muscle_organ = ..., bone = ... } or a number, got " +
                         detail::type_phrase(*n) + " " + detail::show(*n));
  Section sub(s.ctx(), *t, path);
  for (int c = 0; c < kTissueCount; ++c) sub.read(tissue_name(c), out[static_cast<std::size_t>(c)]);
  sub.finish();
}

// tissue.preset is a shorthand, not a field: it sets t1..t3, and t1, t2, t3 given beside it
// override it (so it is read first).
void read_tissue_preset(Section& s, Params& p) {
  std::string preset;
  if (!s.read("preset", preset)) return;
  if (preset == "paper") {
    p.tissue = TissueThresholds{};
  } else if (preset == "robust") {
    p.tissue = TissueThresholds::robust_preset();
  } else {
    fail(s.ctx(), s.get("preset"), "tissue.preset = \"" + preset + "\" is not a preset (valid: \"paper\", \"robust\")");
  }
}

/// material.points: an array of tables, each with every column of the parameter table.
void read_points(Section& s, const std::string& key, std::vector<MaterialPoint>& out) {
  const toml::array* a = s.array(key);
  if (!a) return;
  std::vector<const ParamSpec*> columns;
  for (const ParamSpec& c : param_table())
    if (c.type == ParamType::PointField) columns.push_back(&c);
  std::vector<MaterialPoint> pts;
  for (std::size_t i = 0; i < a->size(); ++i) {
    const toml::node& e = *a->get(i);
    const std::string path = s.path_of(key) + "[" + std::to_string(i) + "]";
    const toml::table* pt = e.as_table();
    if (!pt)
      fail(s.ctx(), &e, path + " must be a table { hu = ..., tau = ..., w = ... }, got " + detail::type_phrase(e) + " " +
                            detail::show(e));
    Section ps(s.ctx(), *pt, path);
    MaterialPoint mp{};
    for (const ParamSpec* c : columns)
      if (!ps.read(c->name(), mp.*(c->point_field)))
        fail(s.ctx(), &e, path + " is missing '" + c->name() + "' (each point needs hu, tau and w)");
    ps.finish();
    pts.push_back(mp);
  }
  out = std::move(pts);
}

/// One section ([tissue], [material], [solver], [dynamics]): every key of the parameter table
/// in it, in the table's order; any other key is an error (Section::finish).
void read_section(Section& root, const std::string& section, Params& p) {
  const toml::table* t = root.table(section);
  if (!t) return;
  Section s(root.ctx(), *t, section);
  if (section == "tissue") read_tissue_preset(s, p);
  for (const ParamSpec& spec : param_table()) {
    if (spec.section() != section) continue;
    const std::string name = spec.name();
    switch (spec.type) {
      case ParamType::Real: s.read(name, spec.real(p)); break;
      case ParamType::Integer: s.read(name, spec.integer(p)); break;
      case ParamType::Flag: s.read(name, spec.flag(p)); break;
      case ParamType::Choice: {
        std::string v;
        if (s.read(name, v)) {
          try {
            spec.set_choice(p, v);
          } catch (const Error& e) {
            fail(s.ctx(), s.get(name), e.what());
          }
        }
        break;
      }
      case ParamType::PerClass: read_per_tissue(s, name, spec.per_class(p)); break;
      case ParamType::Points: read_points(s, name, spec.points(p)); break;
      case ParamType::PointField: break;  // read with their points
    }
  }
  s.finish();
}

/// The sections in file order, as the parameter table lists them.
std::vector<std::string> sections() {
  std::vector<std::string> out;
  for (const ParamSpec& spec : param_table())
    if (out.empty() || out.back() != spec.section()) out.push_back(spec.section());
  return out;
}

// ------------------------------------------------------------------------------------------
// Writing

/// Lines "assignment   # comment" with the comments aligned.
class Writer {
 public:
  void raw(const std::string& line) { flush(), out_ << line << '\n'; }
  void kv(const std::string& assign, const std::string& comment = "") { rows_.push_back({assign, comment}); }
  std::string str() {
    flush();
    return out_.str();
  }

 private:
  void flush() {
    std::size_t w = 0;
    for (auto& r : rows_)
      if (!r.second.empty() && r.first.size() <= 32) w = std::max(w, r.first.size());
    for (auto& r : rows_) {
      out_ << r.first;
      if (!r.second.empty()) out_ << std::string(w + 2 - std::min(w, r.first.size()), ' ') << "# " << r.second;
      out_ << '\n';
    }
    rows_.clear();
  }
  std::ostringstream out_;
  std::vector<std::pair<std::string, std::string>> rows_;
};

std::string per_tissue(const PerTissue& v) {
  std::string s = "{ ";
  for (int c = 0; c < kTissueCount; ++c) {
    if (c) s += ", ";
    s += std::string(tissue_name(c)) + " = " + fmt_float(v[static_cast<std::size_t>(c)]);
  }
  return s + " }";
}

std::string quoted(const char* s) { return std::string("\"") + s + "\""; }

/// The comment of a key: its range (with the unit) and help, from the parameter table.
std::string comment_of(const ParamSpec& spec) {
  std::string c = (spec.type == ParamType::PerClass ? "each in " : "") + range_text(spec);
  if (!spec.unit.empty()) c += " " + spec.unit;
  return c + ": " + spec.help;
}

/// "key = value" in TOML.
std::string assignment(const ParamSpec& spec, const Params& p) {
  Params& q = const_cast<Params&>(p);  // the accessors give references; nothing is written here
  std::string v;
  switch (spec.type) {
    case ParamType::Real: v = fmt_float(spec.real(q)); break;
    case ParamType::Integer: v = std::to_string(spec.integer(q)); break;
    case ParamType::Flag: v = spec.flag(q) ? "true" : "false"; break;
    case ParamType::Choice: v = quoted(spec.choice_name(p).c_str()); break;
    case ParamType::PerClass: v = per_tissue(spec.per_class(q)); break;
    case ParamType::Points:
    case ParamType::PointField: break;  // written by write_points
  }
  return spec.name() + " = " + v;
}

/// points = [ { hu = ..., tau = ..., w = ... }, ... ]; the first row's comment gives each
/// column's range and unit.
void write_points(Writer& w, const Params& p) {
  std::vector<const ParamSpec*> columns;
  std::string legend;
  for (const ParamSpec& c : param_table())
    if (c.type == ParamType::PointField) {
      legend += (columns.empty() ? "" : "; ") + c.name() + " " + range_text(c) + (c.unit.empty() ? "" : " " + c.unit);
      columns.push_back(&c);
    }
  w.raw("points = [");
  for (std::size_t i = 0; i < p.material.points.size(); ++i) {
    std::string row = "  {";
    for (std::size_t k = 0; k < columns.size(); ++k)
      row += (k ? ", " : " ") + columns[k]->name() + " = " + fmt_float(p.material.points[i].*(columns[k]->point_field));
    w.kv(row + " },", i == 0 ? legend : "");
  }
  w.raw("]");
}

/// The prose above each section's keys (what the keys have in common; each key's range and
/// help are the parameter table's).
void section_intro(Writer& w, const std::string& section) {
  if (section == "tissue") {
    w.raw("# Four classes from HU, half-open intervals (SPEC 3): air HU < t1 <= skin_fat < t2");
    w.raw("# <= muscle_organ < t3 <= bone. Thresholds must be finite and strictly increasing.");
    w.raw("# preset = \"paper\" (-1000, 25, 375, the paper's) or \"robust\" (-500, 0, 200: noisy outside air");
    w.raw("# stays air, cancellous bone counts as bone). t1, t2, t3 given beside a preset override it.");
  } else if (section == "material") {
    w.raw("# HP-ChainMail material (SPEC 3): tolerance tau and propagation time penalty w at control");
    w.raw("# points; piecewise linear in HU between them (tau in log space), constant beyond the ends.");
    w.raw("# A link uses the values at its two elements' mean HU: axial spacing in [1 - 0.8 tau, 1 + tau],");
    w.raw("# shear within +-tau. At least 2 points, hu strictly increasing. Giving points replaces the");
    w.raw("# whole list.");
  } else if (section == "dynamics") {
    w.raw("# Independent velocity layer (SPEC 5). Per-class values are tables with the keys air,");
    w.raw("# skin_fat, muscle_organ, bone (a missing class keeps its value) or one number for all.");
  }
}

std::string write_params(const Params& p, const std::string& header) {
  Writer w;
  w.raw(header);
  w.raw("# Every key is optional: a missing key keeps its default. Unknown keys and wrong types are");
  w.raw("# errors. Lengths are in lattice units (one unit = one element spacing), speeds in lattice");
  w.raw("# units per frame. Check a file with: hpcm params --check FILE");
  const std::vector<std::string> all = sections();
  for (const std::string& section : all) {
    w.raw("");
    w.raw("[" + section + "]");
    section_intro(w, section);
    for (const ParamSpec& spec : param_table()) {
      if (spec.section() != section || spec.type == ParamType::PointField) continue;
      if (spec.type == ParamType::Points) write_points(w, p);
      else w.kv(assignment(spec, p), comment_of(spec));
    }
  }
  return w.str();
}

}  // namespace

Params parse_params(const std::string& toml_text, const std::string& source_name) {
  return parse_params(toml_text, source_name, Params{});
}

Params parse_params(const std::string& toml_text, const std::string& source_name, const Params& base) {
  const Ctx ctx{source_name};
  const toml::table root_tbl = detail::parse_toml(toml_text, ctx);
  Params p = base;
  Section root(ctx, root_tbl, "");
  for (const std::string& section : sections()) read_section(root, section, p);
  root.finish();
  try {
    p.validate();
  } catch (const Error& e) {
    throw Error(source_name + ": " + detail::locate_message(root_tbl, e.what()));
  }
  return p;
}

Params load_params(const std::string& path) {
  return parse_params(detail::read_text(path, "parameter file"), path);
}

std::string default_params_toml() {
  return write_params(Params{},
                      "# hpcm parameter file: every default (generated by `hpcm params --defaults`).\n"
                      "# Ranges are given in the comments; see docs/parameters.md.");
}

std::string params_to_toml(const Params& p) {
  return write_params(p, "# hpcm parameter file (see docs/parameters.md; defaults: hpcm params --defaults).");
}

}  // namespace hpcm::config
