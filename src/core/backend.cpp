#include "hpcm/backend.hpp"

#include <atomic>
#include <cmath>
#include <sstream>
#include <utility>

namespace hpcm {

const char* backend_name(BackendKind k) { return k == BackendKind::Cpu ? "cpu" : "cuda"; }

BackendKind parse_backend(const std::string& s, const std::string& what) {
  if (s == "cpu") return BackendKind::Cpu;
  if (s == "cuda") return BackendKind::Cuda;
  throw Error(what + " = '" + s + "' is not one of cpu|cuda");
}

namespace {

std::uint64_t next_revision() {
  static std::atomic<std::uint64_t> counter{0};
  return ++counter;
}

bool finite(Vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string vec_text(Vec3 v) {
  std::ostringstream s;
  s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return s.str();
}

/// Starts a phase of the backend's clock now and ends it when it goes out of scope. A clock
/// that fails (a CUDA error) throws from end(); while a stage's exception unwinds, the
/// destructor ends the phase quietly instead (the stage's error is the one to report).
class ScopedPhase {
 public:
  ScopedPhase(Backend& b, Phase p, void (Backend::*begin)(Phase), void (Backend::*end)(Phase), bool& ran)
      : b_(b), p_(p), end_(end) {
    (b_.*begin)(p_);
    ran = true;
  }
  ~ScopedPhase() {
    if (open_) try {
        (b_.*end_)(p_);
      } catch (...) {
      }
  }
  void end() {
    open_ = false;
    (b_.*end_)(p_);
  }
  ScopedPhase(const ScopedPhase&) = delete;
  ScopedPhase& operator=(const ScopedPhase&) = delete;

 private:
  Backend& b_;
  Phase p_;
  void (Backend::*end_)(Phase);
  bool open_ = true;
};

}  // namespace

const char* phase_name(Phase p) {
  switch (p) {
    case Phase::Snapshot: return "snapshot";
    case Phase::ChainMail: return "chainmail";
    case Phase::Inertia: return "inertia";
    case Phase::FrameEnd: return "frame_end";
  }
  return "?";
}

void Control::set_fixed(std::vector<Index> fixed, std::vector<Vec3> targets, std::vector<std::uint8_t> flags) {
  fixed_ = std::move(fixed);
  targets_ = std::move(targets);
  flags_ = std::move(flags);
  revision_ = next_revision();
}

void Control::validate(const Model& m) const {
  if (targets_.size() != fixed_.size() || flags_.size() != fixed_.size())
    throw Error("control: the FIXED set has " + std::to_string(fixed_.size()) + " elements but " +
                std::to_string(targets_.size()) + " targets and " + std::to_string(flags_.size()) +
                " flags (they must have the same length)");
  const Index n = m.size();
  constexpr unsigned kCallerFlags = kGrabbed | kAnchor;
  for (std::size_t k = 0; k < fixed_.size(); ++k) {
    const Index e = fixed_[k];
    if (e < 0 || e >= n)
      throw Error("control: FIXED entry " + std::to_string(k) + ": element " + std::to_string(e) +
                  " is out of range [0, " + std::to_string(n - 1) + "]");
    if ((flags_[k] & ~kCallerFlags) != 0)
      throw Error("control: FIXED entry " + std::to_string(k) + " (element " + std::to_string(e) + "): flags " +
                  std::to_string(flags_[k]) + " are not one of 0, 2 (grabbed), 4 (anchor), 6 (both)");
    if (!finite(targets_[k]))
      throw Error("control: FIXED entry " + std::to_string(k) + " (element " + std::to_string(e) + "): target " +
                  vec_text(targets_[k]) + " is not finite (a displacement from rest, lattice units)");
  }
}

void Backend::apply_control(const Control& c) {
  c.validate(model());  // before anything changes: a refused control leaves the old set in force
  install_fixed(c);
  applied_revision_ = c.revision();
}

void Backend::notify_model_changed(unsigned changes, const Params& p) {
  p.validate();
  if (changes & (kMaterialsChanged | kAnchorsChanged)) {
    // New classes or links: the current state, reloaded with the new tables.
    State s;
    download(s);
    load(model(), p, s);
  } else if (changes & kParamsChanged) {
    params_changed(p);
  }
}

FrameStats Backend::step(StateHandle in, StateHandle out, const Control& c, const FrameRequest& r) {
  if (!(in == resident()) || !(out == resident()))
    throw Error("step: the states must be this backend's resident state, stepped in place (in == out == resident())");
  if (c.revision() != applied_revision_) apply_control(c);
  begin_frame();
  FrameStats s;
  std::array<bool, kPhaseCount> ran{};
  auto timed = [&](Phase p) {
    return ScopedPhase(*this, p, &Backend::phase_begin, &Backend::phase_end, ran[static_cast<int>(p)]);
  };
  {
    ScopedPhase t = timed(Phase::Snapshot);
    snapshot();  // X- <- X
    t.end();
  }
  {
    ScopedPhase t = timed(Phase::ChainMail);
    // Idle frames relax only: propagating would cancel the inertial motion (SPEC §6).
    if (c.deform()) s.propagate = propagate();
    s.relax = relax(params().solver.relax_sweeps);
    s.restore = restore_links();  // every link back in its box
    t.end();
  }
  s.chainmail_active_bricks = active_bricks();
  // Untimed: the metric is O(N) and measured again only when positions may have changed.
  if (r.link_violation && (!r.link_violation_known || s.chainmail_active_bricks > 0)) {
    download_displacements_since(link_disp_, link_disp_since_);
    s.max_link_violation = link_metrics_.max_link_violation(model(), link_disp_);
    s.link_violation_measured = true;
  }
  {
    ScopedPhase t = timed(Phase::Inertia);
    velocity_layer(r.speeds ? &s.speeds : nullptr);  // X+ -> X_{t+1}, V_t; boundary clamp; frame-end snapshot
    t.end();
  }
  if (r.frame_end_guard) {
    ScopedPhase t = timed(Phase::FrameEnd);
    s.frame_end = restore_frame_end();  // the fold guard (docs/solver.md, "No fold")
    t.end();
  }
  s.active_bricks = active_bricks();
  s.active_elements = active_elements();
  for (int p = 0; p < kPhaseCount; ++p) s.phase_ms[p] = ran[p] ? phase_ms(static_cast<Phase>(p)) : 0.0;
  return s;
}

}  // namespace hpcm
