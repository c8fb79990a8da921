// Parameter files (TOML): every field of hpcm::Params, strict reading, exact round trip.
#include <algorithm>
#include <fstream>
#include <sstream>

#include "toml_util.hpp"
#include "hpcm/config.hpp"

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

void read_tissue(Section& root, Params& p) {
  const toml::table* t = root.table("tissue");
  if (!t) return;
  Section s(root.ctx(), *t, "tissue");
  std::string preset;
  if (s.read("preset", preset)) {
    if (preset == "paper") {
      p.tissue = TissueThresholds{};
    } else if (preset == "robust") {
      p.tissue = TissueThresholds::robust_preset();
    } else {
      fail(s.ctx(), s.get("preset"), "tissue.preset = \"" + preset + "\" is not a preset (valid: \"paper\", \"robust\")");
    }
  }
  s.read("t1", p.tissue.t1);
  s.read("t2", p.tissue.t2);
  s.read("t3", p.tissue.t3);
  s.finish();
}

void read_material(Section& root, Params& p) {
  const toml::table* t = root.table("material");
  if (!t) return;
  Section s(root.ctx(), *t, "material");
  if (const toml::array* a = s.array("points")) {
    std::vector<MaterialPoint> pts;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::node& e = *a->get(i);
      const std::string path = "material.points[" + std::to_string(i) + "]";
      const toml::table* pt = e.as_table();
      if (!pt)
        fail(s.ctx(), &e, path + " must be a table { hu = ..., tau = ..., w = ... }, got " + detail::type_phrase(e) + " " +
                              detail::show(e));
      Section ps(s.ctx(), *pt, path);
      MaterialPoint mp{};
      for (const char* key : {"hu", "tau", "w"}) {
        float* dst = key[0] == 'h' ? &mp.hu : key[0] == 't' ? &mp.tau : &mp.w;
        if (!ps.read(key, *dst)) fail(s.ctx(), &e, path + " is missing '" + key + "' (each point needs hu, tau and w)");
      }
      ps.finish();
      pts.push_back(mp);
    }
    p.material.points = std::move(pts);
  }
  s.finish();
}

void read_solver(Section& root, Params& p) {
  const toml::table* t = root.table("solver");
  if (!t) return;
  Section s(root.ctx(), *t, "solver");
  auto& q = p.solver;
  s.read("grab_radius", q.grab_radius);
  s.read("brick_size", q.brick_size);
  s.read("relax_sweeps", q.relax_sweeps);
  s.read("relax_threshold", q.relax_threshold);
  s.read("relax_omega", q.relax_omega);
  std::string anchors;
  if (s.read("anchors", anchors)) {
    try {
      q.anchors = parse_anchor_mode(anchors, "solver.anchors");
    } catch (const Error& e) {
      fail(s.ctx(), s.get("anchors"), e.what());
    }
  }
  s.read("max_propagation_sweeps", q.max_propagation_sweeps);
  s.read("sleep", q.sleep);
  s.finish();
}

void read_dynamics(Section& root, Params& p) {
  const toml::table* t = root.table("dynamics");
  if (!t) return;
  Section s(root.ctx(), *t, "dynamics");
  auto& d = p.dynamics;
  std::string mode;
  if (s.read("mode", mode)) {
    try {
      d.mode = parse_damping_mode(mode, "dynamics.mode");
    } catch (const Error& e) {
      fail(s.ctx(), s.get("mode"), e.what());
    }
  }
  s.read("alpha", d.alpha);
  s.read("b0", d.b0);
  read_per_tissue(s, "b1", d.b1);
  read_per_tissue(s, "inverse_mass", d.inverse_mass);
  s.read("s_min", d.s_min);
  s.read("s_max", d.s_max);
  s.read("dead_zone", d.dead_zone);
  s.read("v_max", d.v_max);
  s.read("beta", d.beta);
  read_per_tissue(s, "rho", d.rho);
  s.read("margin", d.margin);
  s.read("sleep_speed", d.sleep_speed);
  s.finish();
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

std::string write_params(const Params& p, const std::string& header) {
  Writer w;
  w.raw(header);
  w.raw("# Every key is optional: a missing key keeps its default. Unknown keys and wrong types are");
  w.raw("# errors. Lengths are in lattice units (one unit = one element spacing), speeds in lattice");
  w.raw("# units per frame. Check a file with: hpcm params --check FILE");
  w.raw("");

  w.raw("[tissue]");
  w.raw("# Four classes from HU, half-open intervals (SPEC 3): air HU < t1 <= skin_fat < t2");
  w.raw("# <= muscle_organ < t3 <= bone. Thresholds must be finite and strictly increasing.");
  w.raw("# preset = \"paper\" (-1000, 25, 375, the paper's) or \"robust\" (-500, 0, 200: noisy outside air");
  w.raw("# stays air, cancellous bone counts as bone). t1, t2, t3 given beside a preset override it.");
  w.kv("t1 = " + fmt_float(p.tissue.t1), "HU, air | skin_fat");
  w.kv("t2 = " + fmt_float(p.tissue.t2), "HU, skin_fat | muscle_organ");
  w.kv("t3 = " + fmt_float(p.tissue.t3), "HU, muscle_organ | bone");
  w.raw("");

  w.raw("[material]");
  w.raw("# HP-ChainMail material (SPEC 3): tolerance tau and propagation time penalty w at control");
  w.raw("# points; piecewise linear in HU between them (tau in log space), constant beyond the ends.");
  w.raw("# A link uses the values at its two elements' mean HU: axial spacing in [1 - 0.8 tau, 1 + tau],");
  w.raw("# shear within +-tau. At least 2 points, hu finite and strictly increasing, tau in (0, 1],");
  w.raw("# w in [1e-06, 100]. Giving points replaces the whole list.");
  w.raw("points = [");
  for (std::size_t i = 0; i < p.material.points.size(); ++i) {
    const auto& mp = p.material.points[i];
    w.kv("  { hu = " + fmt_float(mp.hu) + ", tau = " + fmt_float(mp.tau) + ", w = " + fmt_float(mp.w) + " },",
         i == 0 ? "hu, tau (lattice units), w" : "");
  }
  w.raw("]");
  w.raw("");

  w.raw("[solver]");
  w.kv("grab_radius = " + fmt_float(p.solver.grab_radius), "(0, 64] lattice units: elements this close to the grab centre follow the tool");
  w.kv("brick_size = " + std::to_string(p.solver.brick_size), "4 | 8 | 16: edge of the bricks of sparse work");
  w.kv("relax_sweeps = " + std::to_string(p.solver.relax_sweeps), "[0, 256] relaxation sweeps K per frame (early exit)");
  w.kv("relax_threshold = " + fmt_float(p.solver.relax_threshold), "[0, 0.999] lattice units: smaller relaxation corrections are skipped (decides how far a pull reaches)");
  w.kv("relax_omega = " + fmt_float(p.solver.relax_omega), "[1, 1.95] over-relaxation of each relaxation step (1 = plain Gauss-Seidel)");
  w.kv("anchors = " + quoted(anchor_mode_name(p.solver.anchors)), "\"none\" | \"bone\" | \"border\": elements held FIXED every frame");
  w.kv("max_propagation_sweeps = " + std::to_string(p.solver.max_propagation_sweeps), "[1, 10000000] safety cap on propagation sweeps per frame");
  w.kv(std::string("sleep = ") + (p.solver.sleep ? "true" : "false"),
       "true | false: bricks where nothing moves cost nothing; false keeps every brick awake (exact reference)");
  w.raw("");

  w.raw("[dynamics]");
  w.raw("# Independent velocity layer (SPEC 5). Per-class values are tables with the keys air,");
  w.raw("# skin_fat, muscle_organ, bone (a missing class keeps its value) or one number for all.");
  w.kv("mode = " + quoted(damping_mode_name(p.dynamics.mode)), "\"none\" (A) | \"simple\" (B) | \"viscoelastic\" (C); also \"A\", \"B\", \"C\"");
  w.kv("alpha = " + fmt_float(p.dynamics.alpha), "[0, 1], at most 0.99 under simple: V <- alpha V + s dX");
  w.kv("b0 = " + fmt_float(p.dynamics.b0), "[0, 1], at least 0.005 under viscoelastic: V <- (V + s dX) / (1 + b0 + b1 |X - X0|)");
  w.kv("b1 = " + per_tissue(p.dynamics.b1), "each [0, 1]");
  w.kv("inverse_mass = " + per_tissue(p.dynamics.inverse_mass), "each in [0, 1e6], at least one > 0; 0 = no dynamics (bone)");
  w.kv("s_min = " + fmt_float(p.dynamics.s_min), "response scale s = clamp(m^-1 / max m^-1, s_min, s_max),");
  w.kv("s_max = " + fmt_float(p.dynamics.s_max), "0 <= s_min <= s_max <= 1");
  w.kv("dead_zone = " + fmt_float(p.dynamics.dead_zone), "[0, 0.999] lattice units, under simple/viscoelastic at least 3e-4 and at least 2 * solver.relax_threshold: smaller ChainMail corrections dX count as 0");
  w.kv("v_max = " + fmt_float(p.dynamics.v_max), "(0, 10] lattice units / frame: velocity magnitude clamp");
  w.kv("beta = " + fmt_float(p.dynamics.beta), "[0, 2] global inertia gain: X <- X+ + beta rho V");
  w.kv("rho = " + per_tissue(p.dynamics.rho), "each [0, 2] per-class position gain");
  w.kv("margin = " + fmt_float(p.dynamics.margin), "[0, 64] lattice units: positions stay in [-margin, N - 1 + margin]");
  w.kv("sleep_speed = " + fmt_float(p.dynamics.sleep_speed), "[0, 0.01] lattice units / frame: slower velocities come to rest (with solver.sleep)");
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
  read_tissue(root, p);
  read_material(root, p);
  read_solver(root, p);
  read_dynamics(root, p);
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
