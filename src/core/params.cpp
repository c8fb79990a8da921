#include "hpcm/params.hpp"

#include "hpcm/param_table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace hpcm {

const char* damping_mode_name(DampingMode m) {
  switch (m) {
    case DampingMode::None: return "none";
    case DampingMode::Simple: return "simple";
    case DampingMode::Viscoelastic: return "viscoelastic";
  }
  return "?";
}

DampingMode parse_damping_mode(const std::string& s, const std::string& what) {
  if (s == "none" || s == "A") return DampingMode::None;
  if (s == "simple" || s == "B") return DampingMode::Simple;
  if (s == "viscoelastic" || s == "C") return DampingMode::Viscoelastic;
  throw Error(what + " = '" + s + "' is not one of none|simple|viscoelastic (or A|B|C)");
}

const char* anchor_mode_name(AnchorMode m) {
  switch (m) {
    case AnchorMode::None: return "none";
    case AnchorMode::Bone: return "bone";
    case AnchorMode::Border: return "border";
  }
  return "?";
}

AnchorMode parse_anchor_mode(const std::string& s, const std::string& what) {
  if (s == "none") return AnchorMode::None;
  if (s == "bone") return AnchorMode::Bone;
  if (s == "border") return AnchorMode::Border;
  throw Error(what + " = '" + s + "' is not one of none|bone|border");
}

namespace {
// The rules that relate several keys; each key's own range is checked first, from the
// parameter table (param_table.cpp).
void check_some_inverse_mass(const DynamicsParams& d) {
  if (*std::max_element(d.inverse_mass.begin(), d.inverse_mass.end()) <= 0.0f)
    throw Error("dynamics.inverse_mass: at least one class must have an inverse mass > 0");
}

void check_response_clamp_order(const DynamicsParams& d) {
  if (d.s_min > d.s_max) {
    std::ostringstream m;
    m << "dynamics.s_min = " << d.s_min << " must not exceed dynamics.s_max = " << d.s_max;
    throw Error(m.str());
  }
}
}  // namespace

PerTissue DynamicsParams::response_scale() const {
  const float mx = *std::max_element(inverse_mass.begin(), inverse_mass.end());
  PerTissue s{};
  for (int t = 0; t < kTissueCount; ++t) s[t] = std::clamp(mx > 0 ? inverse_mass[t] / mx : 0.0f, s_min, s_max);
  return s;
}

namespace {
// Measured on the 16x16x12 phantom (docs/parameters.md, "Stability"): with little
// over-relaxation (k near 1) settings at 90 % of the linear limit kept moving; a take-back of at
// least kMinTakeBack covers every measured case.
constexpr float kMinTakeBack = 1.15f;
// Near the limit the linear decay is too slow for the nonlinear layer (dead zone, v_max clamp,
// sleeping): 0.998 of the limit grew to 1.5 cells per frame, 0.994 settled.
constexpr float kStabilityMargin = 0.99f;
// The largest share of an element's displacement that one frame of relaxation (K red-black
// sweeps, over-relaxation omega) takes back (k in docs/parameters.md, "Stability"). The
// lattice's 6-neighbour coupling is two-cyclic, so each eigenvalue l of one sweep solves
// (l + omega - 1)^2 = l omega^2 mu^2 for an eigenvalue mu of the Jacobi step (Young's SOR
// theory): real ones lie in (0, 1), the others have modulus |omega - 1| and K sweeps turn them
// by K times their angle. Where that lands on the negative axis a frame takes back
// 1 + |omega - 1|^K of the displacement: it throws the element past rest. At least kMinTakeBack.
float relaxation_take_back(float omega, int sweeps) {
  if (sweeps <= 0) return 0.0f;  // no relaxation: nothing is taken back
  const float k = 1.0f + static_cast<float>(std::pow(std::abs(static_cast<double>(omega) - 1.0), sweeps));
  return std::max(k, kMinTakeBack);
}
}  // namespace

float DynamicsParams::stable_gain_limit(float relax_omega, int relax_sweeps) const {
  // Linearised frame map of one element: x' = (1 - k) x + g V', V' = d (V - s k x), with the
  // velocity decay d = alpha (simple) or 1 / (1 + b0) (viscoelastic, at rest). It is stable
  // while g s < (1 + alpha) (2 - k) / k (simple) or (1 + d) (2 - k) / (d k) (viscoelastic).
  const float k = relaxation_take_back(relax_omega, relax_sweeps);
  constexpr float kNoLimit = std::numeric_limits<float>::infinity();
  if (k == 0.0f) return kNoLimit;
  switch (mode) {
    case DampingMode::None: return kNoLimit;
    case DampingMode::Simple: return kStabilityMargin * (1.0f + alpha) * (2.0f - k) / k;
    case DampingMode::Viscoelastic: {
      const float d = 1.0f / (1.0f + b0);
      return kStabilityMargin * (1.0f + d) * (2.0f - k) / (d * k);
    }
  }
  return kNoLimit;
}

namespace {
// " (to K or more)": the fewest relaxation sweeps that make the setting stable on their own
// (the limit grows with the sweeps), or "" when no count up to 256 does.
std::string sweeps_hint(const Params& p) {
  const PerTissue s = p.dynamics.response_scale();
  float worst = 0.0f;
  for (int t = 0; t < kTissueCount; ++t) worst = std::max(worst, p.dynamics.beta * p.dynamics.rho[t] * s[t]);
  for (int k = p.solver.relax_sweeps + 1; k <= 256; ++k)
    if (worst <= p.dynamics.stable_gain_limit(p.solver.relax_omega, k) * 1.0001f) return " (to " + std::to_string(k) + " or more)";
  return "";
}
}  // namespace

namespace {
// Damping too weak to bring the motion to rest: b0 = 0, alpha = 1 or dead_zone = 0 keep moving
// at about 1e-3 cells per frame forever. Checked for the modes that use them.
// viscoelastic b0 = 0.001, simple alpha = 0.995 (at omega 1.95) and dead_zone = 1e-4 still
// moved after 3,000 frames of the 16x16x12 phantom; at the bounds (params.hpp) it came to rest.
void check_damping_settles(const DynamicsParams& d) {
  std::ostringstream m;
  if (d.mode == DampingMode::Viscoelastic && d.b0 < kMinSettlingB0)
    m << "dynamics.b0 = " << d.b0 << " is below " << kMinSettlingB0 << " under dynamics.mode = viscoelastic";
  else if (d.mode == DampingMode::Simple && d.alpha > kMaxSettlingAlpha)
    m << "dynamics.alpha = " << d.alpha << " is above " << kMaxSettlingAlpha << " under dynamics.mode = simple";
  else if (d.mode != DampingMode::None && d.dead_zone < kMinSettlingDeadZone)
    m << "dynamics.dead_zone = " << d.dead_zone << " is below " << kMinSettlingDeadZone << " with dynamics.mode = "
      << damping_mode_name(d.mode);
  else
    return;
  m << ": the motion would never come to rest (too little damping; stability rule, docs/parameters.md)";
  throw Error(m.str());
}

// The relaxation skips corrections below solver.relax_threshold, so it moves an element either
// not at all or by at least the threshold: for the velocity layer that is a relay, an impulse of
// about the threshold each time an element leaves its dead band, whatever its speed, and it keeps
// an oscillation of that size going for ever (docs/velocity_layer.md, "Dead zone and threshold").
// The layer's dead zone must hide those impulses: at least kDeadZonePerThreshold times the
// threshold (at 1 time the abdomen CT still moved 0.3 cells per frame after 2,000 idle frames).
void check_dead_zone_covers_threshold(const Params& p) {
  if (p.dynamics.mode == DampingMode::None) return;
  const float need = kDeadZonePerThreshold * p.solver.relax_threshold;
  if (p.dynamics.dead_zone >= need) return;
  std::ostringstream m;
  m << "dynamics.dead_zone = " << p.dynamics.dead_zone << " is below " << kDeadZonePerThreshold
    << " * solver.relax_threshold = " << need << " with dynamics.mode = " << damping_mode_name(p.dynamics.mode)
    << ": the relaxation's skipped corrections would keep the motion going for ever; raise dynamics.dead_zone or "
       "lower solver.relax_threshold (stability rule, docs/parameters.md)";
  throw Error(m.str());
}
}  // namespace

void Params::validate() const {
  check_param_ranges(*this);
  tissue.validate();
  material.validate();
  check_some_inverse_mass(dynamics);
  check_response_clamp_order(dynamics);
  check_damping_settles(dynamics);
  check_dead_zone_covers_threshold(*this);
  const float limit = dynamics.stable_gain_limit(solver.relax_omega, solver.relax_sweeps);
  const PerTissue s = dynamics.response_scale();
  for (int t = 0; t < kTissueCount; ++t) {
    const float gain = dynamics.beta * dynamics.rho[t] * s[t];
    if (!(gain <= limit * 1.0001f)) {  // a setting exactly at the limit is accepted
      std::ostringstream m;
      m << "dynamics.beta * dynamics.rho." << tissue_name(t) << " * s(" << tissue_name(t) << ") = " << dynamics.beta
        << " * " << dynamics.rho[t] << " * " << s[t] << " = " << gain << " exceeds the stability limit " << limit
        << " of dynamics.mode = " << damping_mode_name(dynamics.mode)
        << (dynamics.mode == DampingMode::Simple ? " with dynamics.alpha = " : " with dynamics.b0 = ")
        << (dynamics.mode == DampingMode::Simple ? dynamics.alpha : dynamics.b0)
        << ", solver.relax_omega = " << solver.relax_omega << " and solver.relax_sweeps = " << solver.relax_sweeps
        << ": the motion would never settle; lower dynamics.beta or dynamics.rho." << tissue_name(t)
        << (dynamics.mode == DampingMode::Simple ? ", raise dynamics.alpha" : ", raise dynamics.b0")
        << ", lower solver.relax_omega or raise solver.relax_sweeps" << sweeps_hint(*this)
        << " (stability rule, docs/parameters.md)";
      throw Error(m.str());
    }
  }
}

bool materials_differ(const Params& a, const Params& b) {
  return !(a.tissue == b.tissue) || !(a.material == b.material);
}

}  // namespace hpcm
