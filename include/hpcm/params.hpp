#pragma once
// Every user setting of SPEC §3–5 in one struct, with validation. Defaults are the tuned
// values documented in docs/tuning.md; each key's range, unit and help are in the parameter
// table (hpcm/param_table.hpp, src/core/param_table.cpp), the only place they are written.
#include <string>

#include "hpcm/material.hpp"
#include "hpcm/tissue.hpp"

namespace hpcm {

enum class DampingMode { None, Simple, Viscoelastic };  ///< conditions A, B, C
const char* damping_mode_name(DampingMode m);            ///< "none", "simple", "viscoelastic"
/// Parses "none|simple|viscoelastic" (also "A|B|C"); throws hpcm::Error naming `what`.
DampingMode parse_damping_mode(const std::string& s, const std::string& what);

enum class AnchorMode { None, Bone, Border };
const char* anchor_mode_name(AnchorMode m);
AnchorMode parse_anchor_mode(const std::string& s, const std::string& what);

struct SolverParams {
  float grab_radius = 1.5f;        ///< lattice units
  /// Grabbed elements other than the centre that touch an anchored element outside the grab
  /// slip from the tool (are not held): tissue bound to bone or the table does not follow it
  /// (SPEC §4, infeasible requests). false holds every element within the radius.
  bool grab_slip = true;
  int brick_size = 8;              ///< CPU bricks for sparse work
  int relax_sweeps = 8;            ///< K
  float relax_threshold = 0.03f;   ///< lattice units: smaller corrections are skipped (decides the reach, SPEC §8.8)
  float relax_omega = 1.85f;       ///< over-relaxation of each step (1 = Gauss-Seidel)
  /// lattice units: within this distance of rest corrections below relax_threshold are skipped
  /// (ChainMail's slack); farther from rest every correction is applied (solver::relax_step_applies)
  float relax_slack = 1.0f;
  AnchorMode anchors = AnchorMode::Bone;
  int max_propagation_sweeps = 100000;  ///< safety cap
  /// Bricks where nothing moves sleep (cost nothing) until a neighbour, the wave or the tool
  /// wakes them; velocities below dynamics.sleep_speed are set to 0. false keeps every brick
  /// awake and every velocity (the exact reference, slower).
  bool sleep = true;
  friend bool operator==(const SolverParams&, const SolverParams&) = default;
};

/// Damping that still brings the motion to rest (measured, docs/parameters.md "Stability"):
/// Params::validate rejects weaker settings for the modes that use them.
inline constexpr float kMinSettlingB0 = 0.005f;        ///< viscoelastic: b0 at least this
inline constexpr float kMaxSettlingAlpha = 0.99f;      ///< simple: alpha at most this
inline constexpr float kMinSettlingDeadZone = 3e-4f;   ///< simple and viscoelastic: dead_zone at least this
/// simple and viscoelastic: dead_zone at least this many times solver.relax_threshold (the
/// relaxation's skipped corrections act as a relay on the velocity layer; docs/velocity_layer.md).
inline constexpr float kDeadZonePerThreshold = 2.0f;

struct DynamicsParams {
  DampingMode mode = DampingMode::Viscoelastic;
  float alpha = 0.98f;                       ///< simple damping
  float b0 = 0.03f;                          ///< viscoelastic constant term
  PerTissue b1{0.0f, 0.15f, 0.15f, 0.15f};       ///< viscoelastic displacement term; air 0
  PerTissue inverse_mass{1.0f, 1.0f, 0.15f, 0.0f};  ///< at least one > 0
  float s_min = 0.0f, s_max = 1.0f;          ///< response-scale clamp, s_min <= s_max
  float dead_zone = 0.06f;                   ///< lattice units; at least kDeadZonePerThreshold * relax_threshold
  float v_max = 1.0f;                        ///< lattice units per frame
  /// Lattice units per frame: a velocity below it is set to 0 (the element comes to
  /// rest and its brick can sleep); ignored when solver.sleep is false.
  float sleep_speed = 1e-7f;
  float beta = 1.0f;                         ///< global inertia gain
  PerTissue rho{1.0f, 1.0f, 1.0f, 1.0f};     ///< per-class position gain
  float margin = 2.0f;                       ///< boundary margin, lattice units
  /// s_class = clamp(inverse_mass / max(inverse_mass), s_min, s_max) (SPEC §5.3).
  PerTissue response_scale() const;
  /// Largest inertia gain beta * rho_class * s_class with which the motion still settles under
  /// this mode, for a relaxation of `relax_sweeps` sweeps over-relaxed by `relax_omega`
  /// (derived and measured; docs/parameters.md, "Stability"). Infinite for mode none and
  /// without relaxation.
  float stable_gain_limit(float relax_omega, int relax_sweeps) const;
  friend bool operator==(const DynamicsParams&, const DynamicsParams&) = default;
};

struct Params {
  TissueThresholds tissue;
  MaterialTable material;
  SolverParams solver;
  DynamicsParams dynamics;
  /// Validates every part: each key's range (the parameter table), then the rules that relate
  /// keys. The message names the key (e.g. "dynamics.alpha") and range. Also rejects
  /// velocity-layer settings that never settle (the stability rule).
  void validate() const;
  friend bool operator==(const Params&, const Params&) = default;
};

/// True when a and b differ in the tissue thresholds or the material table: the model's classes
/// and links change (Simulation::set_params rebuilds the materials).
bool materials_differ(const Params& a, const Params& b);

}  // namespace hpcm
