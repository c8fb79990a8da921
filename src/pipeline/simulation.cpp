#include "hpcm/simulation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <memory>
#include <sstream>
#include <utility>

#include "solver/neighbours.hpp"
#include "solver/tool_limit.hpp"

#include "pipeline/format_number.hpp"

namespace hpcm {

namespace {
std::string fmt_number(double v) { return detail::format_number(v); }
}  // namespace

void check_grab_radius(float radius, const std::string& what) {
  if (radius >= 0.0f && radius <= kMaxGrabRadius) return;
  std::ostringstream msg;
  msg << what << " = " << radius << " is out of range [0, " << kMaxGrabRadius
      << "] lattice units (0: solver.grab_radius)";
  throw Error(msg.str());
}

void check_grab_radius_mm(const Model& m, float radius_mm, const std::string& what) {
  const Vec3 r = grab_radii_of_mm(m, radius_mm);
  if (radius_mm > 0 && std::max({r.x, r.y, r.z}) <= kMaxGrabRadius) return;
  throw Error(what + " = " + fmt_number(radius_mm) + " is out of range: it must be > 0 mm and at most " +
              fmt_number(kMaxGrabRadius) + " lattice units along every axis (" +
              fmt_number(kMaxGrabRadius * std::min({m.spacing[0], m.spacing[1], m.spacing[2]})) + " mm on this lattice)");
}

Simulation::Simulation(Model model, Params params, BackendKind backend)
    : Simulation(std::move(model), std::move(params), make_backend(backend)) {}

Simulation::Simulation(Model model, Params params, std::unique_ptr<Backend> backend)
    : model_(std::move(model)), params_(std::move(params)), backend_(std::move(backend)) {
  params_.validate();
  const char* skip = std::getenv("HPCM_SKIP_FRAME_END_RESTORE");
  frame_end_restore_ = !(skip && std::string(skip) == "1");
  if (!backend_) throw Error("Simulation: no backend");
  reset();
}

Simulation::~Simulation() = default;

void Simulation::set_params(const Params& p) {
  p.validate();
  unsigned changes = kParamsChanged;
  if (materials_differ(p, params_)) changes |= kMaterialsChanged;
  if (p.solver.anchors != params_.solver.anchors) changes |= kAnchorsChanged;
  params_ = p;
  tool_limit_.reset();  // it reads the model's links and the margin, which may change now
  if (changes & kMaterialsChanged) rebuild_materials(model_, params_);
  backend_->notify_model_changed(changes, params_);
  if (changes & (kMaterialsChanged | kAnchorsChanged)) {
    ++positions_version_;  // reloaded
    compute_anchors();     // bone anchors follow the classes
  }
  compute_tool_limit();
  move_tool(requested_offset_);
}

void Simulation::reset() {
  ++positions_version_;
  host_ = State::rest(model_);
  host_valid_ = true;
  backend_->load(model_, params_, host_);
  compute_anchors();
  grabbed_.clear();
  grab_origin_.clear();
  grab_centre_ = -1;
  tool_offset_ = requested_offset_ = {};
  tool_limit_.reset();
  frame_ = 0;
  push_fixed();
}

void Simulation::compute_anchors() {
  anchors_.clear();
  anchored_.assign(static_cast<std::size_t>(model_.size()), 0);
  if (params_.solver.anchors == AnchorMode::None) return;
  const Int3 d = model_.dims;
  for (Index i = 0; i < model_.size(); ++i) {
    const Int3 c = model_.coords(i);
    const bool border = c.x == 0 || c.y == 0 || c.z == 0 || c.x == d.x - 1 || c.y == d.y - 1 || c.z == d.z - 1;
    // Outside objects that are not air (the CT table) are a rigid support, like bone (SPEC §3).
    const bool bone = model_.tissue[i] == static_cast<std::uint8_t>(Tissue::Bone) || model_.outside_object(i);
    if (params_.solver.anchors == AnchorMode::Border ? border : bone) {
      anchors_.push_back(i);
      anchored_[static_cast<std::size_t>(i)] = 1;
    }
  }
}

void Simulation::compute_tool_limit() {
  tool_limit_.reset();
  if (grabbed_.empty()) return;
  // Grabbed elements move with the tool even where they are anchored (bone under the tool).
  std::vector<std::uint8_t> anchored = anchored_;
  for (Index g : grabbed_) anchored[static_cast<std::size_t>(g)] = 0;
  // Searched lazily: each move_tool() explores only as far as its offset needs.
  tool_limit_ = std::make_unique<solver::ToolLimitSearch>(model_, grabbed_, grab_origin_, std::move(anchored),
                                                          params_.dynamics.margin);
}

Vec3 Simulation::tool_limit_lo() const { return tool_limit_ ? tool_limit_->limit().lo : Vec3{}; }
Vec3 Simulation::tool_limit_hi() const { return tool_limit_ ? tool_limit_->limit().hi : Vec3{}; }

Vec3 grab_radii_of_mm(const Model& m, float radius_mm) {
  return {static_cast<float>(radius_mm / m.spacing[0]), static_cast<float>(radius_mm / m.spacing[1]),
          static_cast<float>(radius_mm / m.spacing[2])};
}

void Simulation::grab(Index centre, float radius) {
  // Before the default is used: a negative or NaN radius must not silently become the default.
  check_grab_radius(radius, "grab radius");
  const float r = radius > 0 ? radius : params_.solver.grab_radius;
  if (!(r <= kMaxGrabRadius))
    throw Error("grab radius " + std::to_string(r) + " is out of range (0, " + fmt_number(kMaxGrabRadius) + "] lattice units");
  grab_within(centre, {r, r, r});
}

void Simulation::grab_mm(Index centre, float radius_mm) {
  check_grab_radius_mm(model_, radius_mm, "grab radius_mm");
  grab_within(centre, grab_radii_of_mm(model_, radius_mm));
}

void Simulation::grab_within(Index centre, Vec3 radii) {
  if (centre < 0 || centre >= model_.size())
    throw Error("grab centre index " + std::to_string(centre) + " is out of range [0, " + std::to_string(model_.size() - 1) + "]");
  grabbed_.clear();
  grab_origin_.clear();
  const Int3 c = model_.coords(centre);
  const Int3 R{static_cast<int>(std::floor(radii.x)), static_cast<int>(std::floor(radii.y)), static_cast<int>(std::floor(radii.z))};
  for (int z = std::max(0, c.z - R.z); z <= std::min(model_.dims.z - 1, c.z + R.z); ++z)
    for (int y = std::max(0, c.y - R.y); y <= std::min(model_.dims.y - 1, c.y + R.y); ++y)
      for (int x = std::max(0, c.x - R.x); x <= std::min(model_.dims.x - 1, c.x + R.x); ++x) {
        // (d / r)^2 summed <= 1: a sphere when the radii are equal.
        const float ux = float(x - c.x) / radii.x, uy = float(y - c.y) / radii.y, uz = float(z - c.z) / radii.z;
        if (ux * ux + uy * uy + uz * uz <= 1.0f) {
          const Index i = model_.index(x, y, z);
          grabbed_.push_back(i);
          grab_origin_.push_back(backend_->displacement(i));
        }
      }
  if (params_.solver.grab_slip) let_bound_elements_slip(centre);
  grab_centre_ = centre;
  tool_offset_ = requested_offset_ = {};
  compute_tool_limit();
  move_tool(Vec3{});
}

void Simulation::let_bound_elements_slip(Index centre) {
  // Bound: a 6-neighbour is anchored and not grabbed itself (a grabbed anchor moves with the
  // tool). Anchored elements and the centre stay held, so a grab on bone holds the bone.
  std::vector<std::uint8_t> in_grab(static_cast<std::size_t>(model_.size()), 0);
  for (Index g : grabbed_) in_grab[static_cast<std::size_t>(g)] = 1;
  const auto bound = [&](Index g) {
    const Int3 c = model_.coords(g);
    bool found = false;
    solver::for_each_face_neighbour(model_.dims.x, model_.dims.y, model_.dims.z, c.x, c.y, c.z, g,
                                    [&](Index n, int, int, Index, Index) {
                                      const auto k = static_cast<std::size_t>(n);
                                      found |= anchored_[k] && !in_grab[k];
                                    });
    return found;
  };
  std::size_t kept = 0;
  for (std::size_t k = 0; k < grabbed_.size(); ++k) {
    const Index g = grabbed_[k];
    if (g != centre && !anchored_[static_cast<std::size_t>(g)] && bound(g)) continue;
    grabbed_[kept] = g;
    grab_origin_[kept] = grab_origin_[k];
    ++kept;
  }
  grabbed_.resize(kept);
  grab_origin_.resize(kept);
}

void Simulation::move_tool(Vec3 offset) {
  if (!std::isfinite(offset.x) || !std::isfinite(offset.y) || !std::isfinite(offset.z))
    throw Error("tool offset must be finite");
  requested_offset_ = offset;
  tool_offset_ = offset;
  if (grabbing() && tool_limit_) tool_offset_ = tool_limit_->clamp(offset);
  push_fixed();
}

void Simulation::release() {
  grabbed_.clear();
  grab_origin_.clear();
  grab_centre_ = -1;
  tool_offset_ = requested_offset_ = {};
  tool_limit_.reset();
  push_fixed();
}

void Simulation::push_fixed() {
  std::vector<Index> idx;
  std::vector<Vec3> targets;
  std::vector<std::uint8_t> flags;
  idx.reserve(anchors_.size() + grabbed_.size());
  for (Index i : anchors_) {
    idx.push_back(i);
    targets.push_back(Vec3{});  // anchored at rest
    flags.push_back(kAnchor);
  }
  for (std::size_t k = 0; k < grabbed_.size(); ++k) {
    idx.push_back(grabbed_[k]);
    targets.push_back(grab_origin_[k] + tool_offset_);
    flags.push_back(kGrabbed);
  }
  control_.set_fixed(std::move(idx), std::move(targets), std::move(flags));
  // Installed now rather than by the next step (which finds it installed): state() shows the
  // new flags at once.
  backend_->apply_control(control_);
}

const std::vector<Vec3>& Simulation::frame_end_displacements() {
  if (end_pos_version_ != positions_version_) {
    backend_->download_displacements_since(end_pos_, end_pos_since_);
    end_pos_version_ = positions_version_;
  }
  return end_pos_;
}

namespace {

/// Per-class speeds |X_end(t) - X_end(t-1)| over the counted elements, as the velocity layer
/// reduces them (SPEC §7), from two host copies of the displacements (u_end(t) - u_end(t-1)).
SpeedStats speeds_between(const Model& m, const std::vector<Vec3>& before, const std::vector<Vec3>& after) {
  std::array<double, kTissueCount> sum{};
  SpeedStats st;
  for (Index i = 0; i < m.size(); ++i) {
    const float sp = norm(after[static_cast<std::size_t>(i)] - before[static_cast<std::size_t>(i)]);
    if (sp > 0) ++st.moved;
    if (!m.counted(i)) continue;
    const int t = m.tissue[static_cast<std::size_t>(i)];
    sum[t] += sp;
    st.max[t] = std::max(st.max[t], sp);
  }
  for (int t = 0; t < kTissueCount; ++t) st.sum[t] = static_cast<float>(sum[t]);
  return st;
}

}  // namespace

FrameReport Simulation::step(const StepOptions& opt) {
  FrameReport r;
  // The speeds of a frame whose end the link restoration changes cannot come from the velocity
  // layer (it measured before the restoration): they are taken on the host from the previous
  // frame's end positions, kept here while speeds are asked for.
  const bool host_speeds = opt.speeds && frame_end_restore_;
  if (host_speeds) {
    frame_end_displacements();
    previous_end_.swap(end_pos_);  // X_end(t-1); end_pos_ is free for this frame's end
    std::swap(previous_end_since_, end_pos_since_);
    end_pos_version_ = ~std::uint64_t{0};
  }
  r.frame = frame_;
  r.deform = grabbing();
  r.grab_offset = r.deform ? norm(tool_offset_) : 0.0f;
  r.requested_offset = r.deform ? norm(requested_offset_) : 0.0f;
  r.grab_offset_mm = r.deform ? offset_length_mm(model_, tool_offset_) : 0.0;
  r.requested_offset_mm = r.deform ? offset_length_mm(model_, requested_offset_) : 0.0;
  r.tool_limited = r.deform && tool_limited();
  control_.set_deform(r.deform);
  FrameRequest req;
  req.speeds = opt.speeds;
  req.link_violation = opt.link_violation;
  req.link_violation_known = link_metric_.version == positions_version_;
  req.frame_end_guard = frame_end_restore_;
  const FrameStats fs = backend_->step(backend_->resident(), backend_->resident(), control_, req);
  r.propagate_sweeps = fs.propagate.sweeps;
  r.propagate_converged = fs.propagate.converged;
  r.relax_sweeps = fs.relax.sweeps;
  r.restored_links = fs.restore.violated_links;
  r.restore_violation = fs.restore.max_violation;
  // The integrity metrics are O(N): measured again only when positions may have changed
  // (some brick had work), else the last values hold exactly.
  if (fs.chainmail_active_bricks > 0) ++positions_version_;
  if (fs.link_violation_measured) link_metric_ = {positions_version_, fs.max_link_violation, 0};
  if (opt.link_violation) r.max_link_violation = link_metric_.value;
  // The layer moves neighbours by different steps (V differs by class, dead zone, clamp, FIXED
  // neighbours) and the boundary clamp flattens: the fold guard unfolds the cells the layer
  // folded and leaves every other element where the layer put it, so the swing is the layer's.
  r.end_folded_cells = fs.frame_end.violated_links;
  r.end_guard_moved = fs.frame_end.moved;
  r.restore_converged = !fs.restore.capped && !fs.frame_end.capped;
  if (fs.frame_end.moved > 0) ++positions_version_;
  if (fs.active_bricks > fs.chainmail_active_bricks) ++positions_version_;
  SpeedStats sp = fs.speeds;
  if (host_speeds && r.end_guard_moved > 0) sp = speeds_between(model_, previous_end_, frame_end_displacements());
  if (opt.cell_jacobian) {
    if (jacobian_metric_.version != positions_version_) {
      const CellJacobianStats cj = jacobian_metrics_.cell_jacobian(model_, frame_end_displacements());
      jacobian_metric_ = {positions_version_, cj.min_det, cj.folded};
    }
    r.min_cell_jacobian = jacobian_metric_.value;
    r.folded_cells = jacobian_metric_.count;
  }
  const auto ms = [&](Phase p) { return fs.phase_ms[static_cast<int>(p)]; };
  r.snapshot_ms = ms(Phase::Snapshot);
  r.chainmail_ms = ms(Phase::ChainMail) + ms(Phase::FrameEnd);  // the frame-end guard is ChainMail work
  r.inertia_ms = ms(Phase::Inertia);
  r.sim_total_ms = r.snapshot_ms + r.chainmail_ms + r.inertia_ms;
  r.active_bricks = fs.active_bricks;
  r.active_elements = fs.active_elements;
  if (opt.speeds) {
    r.moved_elements = sp.moved;
    const auto& count = model_.counted_class_count;  // the body's elements (every element without one)
    for (int t = 0; t < kTissueCount; ++t) {
      r.mean_speed[t] = count[t] > 0 ? sp.sum[t] / static_cast<float>(count[t]) : 0.0f;
      r.max_speed[t] = sp.max[t];
    }
  }
  ++frame_;
  host_valid_ = false;
  return r;
}

const State& Simulation::state() {
  if (!host_valid_) {
    backend_->download_since(host_, host_since_);
    host_valid_ = true;
  }
  return host_;
}

}  // namespace hpcm
