#include "hpcm/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "pipeline/format_number.hpp"

namespace hpcm {

namespace {
std::string number(double v) { return detail::format_number(v); }
}  // namespace

Scenario Scenario::paper_protocol(float distance, int pull, int hold, int record) {
  if (!(distance >= 0 && distance <= 1000) || pull < 1 || hold < 0 || record < 1)
    throw Error("paper protocol: distance in [0, 1000], pull >= 1, hold >= 0, record >= 1 required");
  Scenario s;
  s.name = "paper_protocol";
  GrabAction g;
  g.start = 0;
  g.path = {{0, {0, 0, 0}}, {pull, {0, -distance, 0}}};  // anterior is -y
  g.release = pull + hold;
  s.grabs.push_back(g);
  s.frames = pull + hold + record;
  return s;
}

Scenario Scenario::in_lattice_units(const Model& m) const {
  Scenario out = *this;
  for (std::size_t k = 0; k < out.grabs.size(); ++k)
    for (std::size_t j = 0; j < out.grabs[k].path.size(); ++j) {
      Keyframe& kf = out.grabs[k].path[j];
      if (kf.units != Units::mm) continue;
      const Vec3 mm = kf.offset;
      kf.offset = lattice_offset_of_mm(m, mm);
      kf.units = Units::lattice;
      if (!(std::fabs(kf.offset.x) <= kMaxToolOffset && std::fabs(kf.offset.y) <= kMaxToolOffset &&
            std::fabs(kf.offset.z) <= kMaxToolOffset))
        throw Error("scenario '" + name + "': grab[" + std::to_string(k) + "].keyframes[" + std::to_string(j) +
                    "].offset_mm (" + number(mm.x) + ", " + number(mm.y) + ", " + number(mm.z) +
                    ") mm is out of range: at most " + number(kMaxToolOffset) + " lattice units per axis (spacing " +
                    number(m.spacing[0]) + " x " + number(m.spacing[1]) + " x " + number(m.spacing[2]) + " mm)");
    }
  return out;
}

float widest_grab_radius(const GrabAction& g, const Model& m, float default_radius) {
  if (g.radius_units == Units::mm) {
    const Vec3 r = grab_radii_of_mm(m, g.radius);
    return std::max({r.x, r.y, r.z});
  }
  return g.radius > 0 ? g.radius : default_radius;
}

int Scenario::last_release_frame() const {
  int r = -1;
  for (const auto& g : grabs) r = std::max(r, g.start + g.release);
  return r;
}

void Scenario::validate(const Model& m) const {
  if (frames < 1) throw Error("scenario '" + name + "': frames = " + std::to_string(frames) + " must be >= 1");
  for (std::size_t k = 0; k < grabs.size(); ++k) {
    const auto& g = grabs[k];
    const std::string key = "scenario '" + name + "': grab[" + std::to_string(k) + "]";
    if (g.centre) {
      const Int3 c = *g.centre;
      if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= m.dims.x || c.y >= m.dims.y || c.z >= m.dims.z)
        throw Error(key + ".centre (" + std::to_string(c.x) + "," + std::to_string(c.y) + "," + std::to_string(c.z) +
                    ") is outside the lattice " + std::to_string(m.dims.x) + "x" + std::to_string(m.dims.y) + "x" +
                    std::to_string(m.dims.z));
    }
    if (g.start < 0) throw Error(key + ".start must be >= 0");
    if (g.release < 1) throw Error(key + ".release must be >= 1");
    if (g.radius_units == Units::mm) {
      check_grab_radius_mm(m, g.radius, key + ".radius_mm");
    } else {
      check_grab_radius(g.radius, key + ".radius");
    }
    for (std::size_t j = 0; j < g.path.size(); ++j) {
      const auto& kf = g.path[j];
      if (kf.frame < 0 || (j > 0 && kf.frame <= g.path[j - 1].frame))
        throw Error(key + ".keyframes[" + std::to_string(j) + "]: frames must be >= 0 and strictly increasing");
      if (!(std::fabs(kf.offset.x) <= kMaxToolOffset && std::fabs(kf.offset.y) <= kMaxToolOffset &&
            std::fabs(kf.offset.z) <= kMaxToolOffset))
        throw Error(key + ".keyframes[" + std::to_string(j) + "]: offset must be finite and within [-" + number(kMaxToolOffset) +
                    ", " + number(kMaxToolOffset) + "] lattice units per axis");
    }
    for (std::size_t j = 0; j < k; ++j) {
      const auto& o = grabs[j];
      if (g.start < o.start + o.release && o.start < g.start + g.release)
        throw Error(key + " overlaps grab[" + std::to_string(j) + "] in time: grabs run in sequence");
    }
  }
}

Vec3 path_offset(const GrabAction& g, int r) {
  if (g.path.empty()) return {};
  const float t = static_cast<float>(r + 1);  // offset reached at the end of relative frame r
  if (t <= g.path.front().frame) {
    const auto& k0 = g.path.front();
    if (k0.frame <= 0) return k0.offset;
    return (t / k0.frame) * k0.offset;  // from the grab point (offset 0 at frame 0)
  }
  for (std::size_t j = 1; j < g.path.size(); ++j)
    if (t <= g.path[j].frame) {
      const auto &a = g.path[j - 1], &b = g.path[j];
      const float u = (t - a.frame) / static_cast<float>(b.frame - a.frame);
      return a.offset + u * (b.offset - a.offset);
    }
  return g.path.back().offset;
}

ScenarioPlayer::ScenarioPlayer(const Scenario& s, Simulation& sim) : scenario_(s.in_lattice_units(sim.model())), sim_(sim) {
  scenario_.validate(sim.model());
  for (std::size_t k = 0; k < scenario_.grabs.size(); ++k) {
    const GrabAction& g = scenario_.grabs[k];
    check_lattice_extent(sim.model(), widest_grab_radius(g, sim.model(), sim.params().solver.grab_radius),
                         "scenario '" + scenario_.name + "': grab[" + std::to_string(k) + "]");
  }
  for (const auto& g : scenario_.grabs)
    centres_.push_back(g.centre ? sim.model().index(g.centre->x, g.centre->y, g.centre->z) : paper_grab_centre(sim.model()));
}

ScenarioPlace scenario_place(const Scenario& sc, int frame) {
  ScenarioPlace p;
  for (std::size_t k = 0; k < sc.grabs.size() && frame >= 0; ++k) {
    const GrabAction& g = sc.grabs[k];
    if (frame < g.start || frame > g.start + g.release) continue;
    p.grab = static_cast<int>(k);
    p.text = "grab[" + std::to_string(k) + "]";
    // Keyframe segment that frame lies in (offsets are reached at the end of relative frame r).
    const int t = frame - g.start + 1;
    for (std::size_t j = 0; j < g.path.size(); ++j)
      if (t <= g.path[j].frame || j + 1 == g.path.size()) {
        p.segment = static_cast<int>(j);
        p.text += j == 0 ? ", keyframes[0]" : ", keyframes[" + std::to_string(j - 1) + "] to [" + std::to_string(j) + "]";
        break;
      }
    break;
  }
  return p;
}

std::optional<LimitedPull> LimitedPullTracker::after_frame(const FrameReport& r, Vec3 achieved, Vec3 requested) {
  std::optional<LimitedPull> ended;
  const ScenarioPlace place = r.tool_limited ? scenario_place(scenario_, r.frame) : ScenarioPlace{};
  const bool continues = open_ && r.tool_limited && open_->last_frame + 1 == r.frame && open_->place.grab == place.grab &&
                         open_->place.segment == place.segment;
  if (open_ && !continues) {
    ended = std::move(open_);
    open_.reset();
  }
  if (!r.tool_limited) return ended;
  if (!open_) open_ = LimitedPull{place, r.frame, r.frame, achieved, requested};
  open_->last_frame = r.frame;
  if (norm(requested) >= norm(open_->requested)) {
    open_->requested = requested;
    open_->achieved = achieved;
  }
  return ended;
}

std::optional<LimitedPull> LimitedPullTracker::finish() {
  std::optional<LimitedPull> ended = std::move(open_);
  open_.reset();
  return ended;
}

FrameReport ScenarioPlayer::step(const StepOptions& opt) {
  for (std::size_t k = 0; k < scenario_.grabs.size(); ++k) {
    const auto& g = scenario_.grabs[k];
    if (frame_ == g.start) {
      if (g.radius_units == Units::mm) sim_.grab_mm(centres_[k], g.radius);
      else sim_.grab(centres_[k], g.radius);
    }
    if (frame_ >= g.start && frame_ < g.start + g.release) sim_.move_tool(path_offset(g, frame_ - g.start));
    if (frame_ == g.start + g.release) sim_.release();
  }
  ++frame_;
  return sim_.step(opt);
}

}  // namespace hpcm
