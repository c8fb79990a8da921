// Scenario files (TOML): scripted grabs with keyframed drag paths, or the paper protocol.
#include <cmath>
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

constexpr int kMaxFrames = 10'000'000;
constexpr float kMaxRadius = kMaxGrabRadius;  // Simulation's rule for a grab radius
// Tool offsets beyond any lattice are meaningless; the bound also keeps the interpolation
// between keyframes and |offset| finite (two offsets near FLT_MAX would overflow).
constexpr float kMaxOffset = 10000.0f;

std::string range_msg(const std::string& path, long long v, long long lo, long long hi) {
  return path + " = " + std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
}

int read_int_in(Section& s, std::string_view key, int lo, int hi, bool required, int fallback, const toml::node* owner,
                const std::string& hint = "") {
  int v = fallback;
  if (!s.read(key, v)) {
    if (required) fail(s.ctx(), owner, s.path_of(key) + " is missing" + hint);
    return v;
  }
  if (v < lo || v > hi) fail(s.ctx(), s.get(key), range_msg(s.path_of(key), v, lo, hi));
  return v;
}

Scenario read_paper(const Ctx& ctx, const toml::node& n) {
  if (auto* b = n.as_boolean()) {
    if (!b->get()) fail(ctx, &n, "paper = false: remove the key and describe the grabs with [[grab]] instead");
    return Scenario::paper_protocol();
  }
  const toml::table* t = n.as_table();
  if (!t)
    fail(ctx, &n, "paper must be true or a table { distance, pull, hold, record }, got " + detail::type_phrase(n) + " " +
                      detail::show(n));
  Section s(ctx, *t, "paper");
  float distance = 6.0f;
  if (s.read("distance", distance) && !(distance >= 0.0f && distance <= 1000.0f))
    fail(ctx, s.get("distance"), "paper.distance = " + fmt_float(distance) + " is out of range [0, 1000] lattice units");
  const int pull = read_int_in(s, "pull", 1, kMaxFrames, false, 20, t);
  const int hold = read_int_in(s, "hold", 0, kMaxFrames, false, 10, t);
  const int record = read_int_in(s, "record", 1, kMaxFrames, false, 120, t);
  s.finish();
  try {
    return Scenario::paper_protocol(distance, pull, hold, record);
  } catch (const Error& e) {
    fail(ctx, &n, e.what());
  }
}

GrabAction read_grab(const Ctx& ctx, const toml::node& n, std::size_t k, int frames) {
  const std::string path = "grab[" + std::to_string(k) + "]";
  const toml::table* t = n.as_table();
  if (!t) fail(ctx, &n, path + " must be a table ([[grab]]), got " + detail::type_phrase(n) + " " + detail::show(n));
  Section s(ctx, *t, path);
  GrabAction g;

  if (const toml::node* c = s.get("centre")) {
    const std::string cpath = path + ".centre";
    if (auto* str = c->as_string()) {
      if (str->get() != "auto") fail(ctx, c, cpath + " = " + detail::show(*c) + " must be \"auto\" or [x, y, z]");
    } else if (auto* a = c->as_array(); a && a->size() == 3) {
      int xyz[3];
      for (std::size_t i = 0; i < 3; ++i) {
        const std::string ip = cpath + "[" + std::to_string(i) + "]";
        xyz[i] = detail::to_int(ctx, *a->get(i), ip);
        if (xyz[i] < 0) fail(ctx, a->get(i), ip + " = " + std::to_string(xyz[i]) + " must be >= 0 (element coordinates)");
      }
      g.centre = Int3{xyz[0], xyz[1], xyz[2]};
    } else {
      fail(ctx, c, cpath + " must be \"auto\" or an array of 3 element coordinates [x, y, z], got " + detail::type_phrase(*c) +
                       " " + detail::show(*c));
    }
  }

  if (s.read("radius", g.radius) && !(g.radius >= 0.0f && g.radius <= kMaxRadius))
    fail(ctx, s.get("radius"),
         path + ".radius = " + fmt_float(g.radius) + " is out of range [0, 64] lattice units (0: solver.grab_radius)");

  g.start = read_int_in(s, "start", 0, frames - 1, false, 0, t);
  g.release = read_int_in(s, "release", 1, kMaxFrames, true, 0, t,
                          " (frames after the grab's start at which it is released, >= 1)");

  if (const toml::array* kfs = s.array("keyframes")) {
    for (std::size_t i = 0; i < kfs->size(); ++i) {
      const toml::node& e = *kfs->get(i);
      const std::string kp = path + ".keyframes[" + std::to_string(i) + "]";
      const toml::array* a = e.as_array();
      if (!a || a->size() != 4)
        fail(ctx, &e, kp + " must be [frame, dx, dy, dz], got " + detail::type_phrase(e) + " " + detail::show(e));
      Keyframe kf;
      kf.frame = detail::to_int(ctx, *a->get(0), kp + "[0] (frame)");
      kf.offset.x = detail::to_float(ctx, *a->get(1), kp + "[1] (dx)");
      kf.offset.y = detail::to_float(ctx, *a->get(2), kp + "[2] (dy)");
      kf.offset.z = detail::to_float(ctx, *a->get(3), kp + "[3] (dz)");
      if (kf.frame < 0 || kf.frame > kMaxFrames) fail(ctx, &e, range_msg(kp + " frame", kf.frame, 0, kMaxFrames));
      const char* axis[3] = {"dx", "dy", "dz"};
      const float d[3] = {kf.offset.x, kf.offset.y, kf.offset.z};
      for (int a = 0; a < 3; ++a)
        if (!(std::fabs(d[a]) <= kMaxOffset))
          fail(ctx, &e, kp + "[" + std::to_string(a + 1) + "] (" + axis[a] + ") = " + fmt_float(d[a]) +
                            " is out of range [-10000, 10000] lattice units");
      if (!g.path.empty() && kf.frame <= g.path.back().frame)
        fail(ctx, &e,
             kp + " frame " + std::to_string(kf.frame) + " must be greater than the previous keyframe's frame " +
                 std::to_string(g.path.back().frame) + " (keyframe frames strictly increase)");
      g.path.push_back(kf);
    }
  }
  s.finish();
  return g;
}

std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (unsigned char ch : s) {
    switch (ch) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (ch < 0x20 || ch == 0x7f) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", ch);
          out += buf;
        } else {
          out += static_cast<char>(ch);
        }
    }
  }
  return out + "\"";
}

}  // namespace

Scenario parse_scenario(const std::string& toml_text, const std::string& source_name) {
  const Ctx ctx{source_name};
  const toml::table root_tbl = detail::parse_toml(toml_text, ctx);
  Section root(ctx, root_tbl, "");

  std::string name;
  bool have_name = false;
  int frames = 0;
  const toml::table* st = root.table("scenario");
  const toml::node* frames_node = nullptr;
  if (st) {
    Section s(ctx, *st, "scenario");
    have_name = s.read("name", name);
    frames_node = s.get("frames");
    if (frames_node) frames = read_int_in(s, "frames", 1, kMaxFrames, true, 0, st);
    s.finish();
  }

  const toml::node* paper = root.get("paper");
  const toml::array* grabs = root.array("grab");
  root.finish();

  Scenario sc;
  if (paper) {
    if (grabs) fail(ctx, grabs, "paper cannot be combined with [[grab]] (use one or the other)");
    if (frames_node)
      fail(ctx, frames_node, "scenario.frames cannot be combined with paper (the protocol sets it; use paper.record)");
    sc = read_paper(ctx, *paper);
    if (have_name) sc.name = name;
    return sc;
  }

  if (!frames_node)
    fail(ctx, nullptr,
         "scenario.frames is missing: give [scenario] frames = N (N >= 1) with [[grab]] tables, or paper = true");
  sc.frames = frames;
  if (have_name) sc.name = name;
  if (grabs) {
    for (std::size_t k = 0; k < grabs->size(); ++k) {
      GrabAction g = read_grab(ctx, *grabs->get(k), k, frames);
      if (!sc.grabs.empty()) {
        const GrabAction& prev = sc.grabs.back();
        const long long prev_end = static_cast<long long>(prev.start) + prev.release;
        if (g.start < prev_end)
          fail(ctx, grabs->get(k),
               "grab[" + std::to_string(k) + "].start = " + std::to_string(g.start) + " overlaps grab[" +
                   std::to_string(k - 1) + "], which is held until frame " + std::to_string(prev_end) +
                   " (grabs play in sequence: start >= previous start + release)");
      }
      sc.grabs.push_back(std::move(g));
    }
  }
  return sc;
}

Scenario load_scenario(const std::string& path) {
  return parse_scenario(detail::read_text(path, "scenario file"), path);
}

std::string scenario_to_toml(const Scenario& s) {
  std::ostringstream o;
  // "key = value" padded so the comments line up.
  auto line = [&o](const std::string& assign, const char* comment) {
    o << assign;
    if (comment) o << std::string(assign.size() < 22 ? 22 - assign.size() : 2, ' ') << "# " << comment;
    o << '\n';
  };
  o << "# hpcm scenario file (see docs/scenarios.md). Frames are simulation frames; offsets are in\n"
       "# lattice units, x: right->left, y: anterior->posterior (anterior = -y), z: inferior->superior.\n\n";
  o << "[scenario]\n";
  line("name = " + toml_string(s.name), nullptr);
  line("frames = " + std::to_string(s.frames), "total frames to play, >= 1");
  for (std::size_t k = 0; k < s.grabs.size(); ++k) {
    const GrabAction& g = s.grabs[k];
    o << "\n[[grab]]\n";
    if (g.centre)
      line("centre = [" + std::to_string(g.centre->x) + ", " + std::to_string(g.centre->y) + ", " +
               std::to_string(g.centre->z) + "]",
           "element coordinates, or \"auto\"");
    else
      line("centre = \"auto\"", "the paper's grab point: body surface along x = Nx/2, central slice");
    line("radius = " + fmt_float(g.radius), "lattice units, [0, 64]; 0: solver.grab_radius");
    line("start = " + std::to_string(g.start), "scenario frame at which the grab begins");
    line("release = " + std::to_string(g.release), "frames after start at which it is released, >= 1");
    o << "# [frame, dx, dy, dz]: tool offset reached `frame` frames after start; linear from 0 before\n"
         "# the first key and between keys, held after the last; frames strictly increase.\n";
    o << "keyframes = [";
    if (g.path.empty()) {
      o << "]\n";
    } else {
      o << "\n";
      for (const Keyframe& kf : g.path)
        o << "  [" << kf.frame << ", " << fmt_float(kf.offset.x) << ", " << fmt_float(kf.offset.y) << ", "
          << fmt_float(kf.offset.z) << "],\n";
      o << "]\n";
    }
  }
  return o.str();
}

}  // namespace hpcm::config
