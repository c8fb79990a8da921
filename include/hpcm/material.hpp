#pragma once
// Heterogeneous HP-ChainMail material: tolerance tau and time penalty w from HU by
// piecewise-linear interpolation through control points (tau in log space), SPEC §3.
#include <vector>

#include "hpcm/types.hpp"

namespace hpcm {

struct MaterialPoint {
  float hu;   ///< control-point HU
  float tau;  ///< tolerance in lattice units, > 0
  float w;    ///< propagation time penalty, > 0
  friend bool operator==(const MaterialPoint&, const MaterialPoint&) = default;
};

/// Box limits of one link (Gibson), as limits on the difference of its ends' displacements from
/// rest (u = X - X0): axial stretch u_hi - u_lo (the spacing minus 1) in [min_stretch,
/// max_stretch], |shear| <= shear across the link. Stretches rather than spacings: the solver
/// works on displacements (docs/solver.md, "Displacements from rest").
struct LinkLimits {
  float min_stretch, max_stretch, shear, w;
};

/// Shear limit of a link of tolerance tau: tau (SPEC §3), capped where tau > 0.35 (air) so
/// that a lattice whose links are all within their boxes never folds. At any cell corner the
/// three edges form the columns of the cell's Jacobian; each column's axial component is at
/// least 1 - 0.8 tau and its two shear components are at most this limit, so every column is
/// diagonally dominant by at least 0.02 and the determinant is positive (docs/solver.md).
/// Written once over the lane type T: float (host and device) or a GCC vector of floats (the
/// CPU's SIMD kernels rebuild each link's box from its tolerance, lane by lane).
template <class T>
HPCM_HD inline T shear_limit(T tau) {
  const T cap = 0.5f * (0.98f - 0.8f * tau);
  return tau < cap ? tau : cap;
}

/// A link's box on lane type T (LinkLimits without the time penalty): stretch in
/// [min_stretch, max_stretch], |shear| <= shear across the link.
template <class T>
struct LinkBox {
  T min_stretch, max_stretch, shear;
};

/// The box of a link of tolerance tau: spacing in [1 - 0.8 tau, 1 + tau] (SPEC §3), so
/// stretch in [-0.8 tau, tau], and shear_limit(tau) across it. The one definition of the box:
/// limits_from_tau (the model's link table) and the SIMD kernels use it.
template <class T>
HPCM_HD inline LinkBox<T> box_from_tau(T tau) {
  return {-(0.8f * tau), tau, shear_limit(tau)};
}

/// The limits of a link of tolerance tau and time penalty w (box_from_tau).
HPCM_HD inline LinkLimits limits_from_tau(float tau, float w) {
  const LinkBox<float> b = box_from_tau(tau);
  return {b.min_stretch, b.max_stretch, b.shear, w};
}

/// The least column dominance the fold guard accepts at a link (column_dominance): where every
/// edge of a cell has at least this, every corner determinant is at least its cube (1e-6) > 0.
/// Links in their boxes have at least 0.02 (the shear cap), so the guard never looks at them.
inline constexpr float kFoldDominance = 0.01f;

/// The column dominance of a link along axis a with ends displaced by u_lo and u_hi from rest:
/// its axial spacing minus its two shear offsets, 1 + (u_hi - u_lo)_a - sum_{b != a}
/// |(u_hi - u_lo)_b|. A cell corner's Jacobian has the three edges leaving the corner as columns;
/// where each has a positive dominance d_a, det >= prod_a d_a > 0 (Ostrowski's bound), so a
/// cell can fold only where one of its edges has a dominance of 0 or less (docs/solver.md, "No
/// fold"). Stretching never folds.
HPCM_HD inline float column_dominance(const Vec3& u_lo, const Vec3& u_hi, int a) {
  const Vec3 d = u_hi - u_lo;
  float dominance = 1.0f + d[a];
  for (int b = 0; b < 3; ++b)
    if (b != a) dominance -= d[b] < 0.0f ? -d[b] : d[b];
  return dominance;
}

/// Range of the link time penalty w. The propagation's time buckets are w_min wide; arrival
/// times reach (path length) * w_max, so w_max / w_min bounds the bucket numbers (they must fit
/// 64 bits at 2^31 elements: 100 / 1e-6 * 2^31 < 2^64).
inline constexpr float kMinLinkPenalty = 1e-6f;
inline constexpr float kMaxLinkPenalty = 100.0f;

struct MaterialTable {
  /// Defaults: air, fat, muscle/organ, bone (SPEC §3 table).
  std::vector<MaterialPoint> points{{-1000.f, 0.5f, 1.0f}, {-100.f, 0.35f, 0.6f}, {50.f, 0.22f, 0.3f}, {700.f, 0.005f, 0.02f}};

  /// Throws hpcm::Error unless there are at least 2 points with HU strictly increasing. The
  /// columns' own ranges (hu finite, tau in (0, 1], w in [kMinLinkPenalty, kMaxLinkPenalty])
  /// are the parameter table's: Params::validate runs both.
  void validate() const;
  /// Interpolated values; constant beyond the first and last control point.
  float tau(float hu) const;
  float w(float hu) const;
  /// Link between two elements: values at the pair's mean HU (symmetric).
  LinkLimits link(float hu_a, float hu_b) const;
  /// Limits of a link whose pair has mean HU `hu`.
  LinkLimits link_at(float hu) const { return limits_from_tau(tau(hu), w(hu)); }
  friend bool operator==(const MaterialTable&, const MaterialTable&) = default;
};

}  // namespace hpcm
