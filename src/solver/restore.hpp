#pragma once
// Link restoration (docs/solver.md, "Every link in its box"): the last step of every ChainMail
// stage puts every link back into its box when something left it there (inertia pushed an
// element out of its box, or two wave fronts met with conflicting boxes), without moving a
// FIXED element and without leaving the boundary box.
//
// Gibson's boxes constrain each coordinate axis separately, so restoration works one axis at
// a time on the difference constraints x_lo(link) - x_hi(link) within the link's interval.
// Two one-sided passes are exact on such systems:
//   lower:  every free element takes min(x_e, every upper bound its neighbours' boxes and the
//           wall put on it), repeated until nothing changes (the greatest consistent
//           configuration below x);
//   raise:  the mirror image with lower bounds and max.
// Because the FIXED elements are mutually consistent (the tool is limited, solver/tool_limit),
// raise(lower(x)) and lower(raise(x)) are both consistent and keep every FIXED element; their
// midpoint is consistent too (the feasible set is convex) and has no bias toward either
// direction. The midpoint is rounded, which can leave a link slightly outside its box, so a last
// lower and raise pass from the midpoints puts every link back, within half a float step of the
// displacements involved (the bounds rounded to nearest): at most 3.8e-6 for displacements
// below 128 cells, below kRestoreTolerance, wherever the element sits (positions are
// displacements from rest, core/link_box.hpp). docs/solver.md, "Displacements from rest".
// Each pass is a monotone fixed-point iteration, so its result does not depend on the order in
// which elements are visited: any schedule (sequential work list, parallel chaotic sweeps on
// the GPU) gives the same floats. Every schedule still caps its work (kRestoreVisitsPerElement)
// and reports a pass that reached the cap (RestoreStats::capped) instead of looping on.
#include "core/link_box.hpp"
#include "solver/rules.hpp"

namespace hpcm::solver {

/// Links (and boundary-box excursions) beyond this are restored. Well below the 1e-5 of the
/// integrity check; above half a float step of a displacement below 128 cells (3.8e-6), so the
/// rounding of the clamps does not call the restoration there (nor finds a restored link
/// violated again).
inline constexpr float kRestoreTolerance = 4e-6f;

/// The cap on one restoration pass: element visits per element the restoration can reach (its
/// lattice). A pass lowers (or raises) each coordinate monotonically, one float step at least per
/// change, so it ends; the cap makes "ends" a bound in every schedule, and a pass that reaches it
/// stops there and says so (RestoreStats::capped) rather than running on.
inline constexpr int kRestoreVisitsPerElement = 64;

/// Whether the link along axis a (ends displaced by u_lo and u_hi from rest) may take part in a
/// fold: its column dominance is below kFoldDominance. Only such a link can be an edge of a
/// folded cell, and it lies outside its box (the shear cap gives a link in its box 0.02). The
/// frame-end fold guard's test on both backends.
HPCM_HD inline bool may_fold(const Vec3& u_lo, const Vec3& u_hi, int a) { return column_dominance(u_lo, u_hi, a) < kFoldDominance; }

/// How far displacement x of element e on axis b lies outside the interval its link to neighbour
/// n (displacement cn on that axis) allows, by the same float arithmetic as link_violation (0 inside).
HPCM_HD inline float link_excess(float x, float cn, const LinkLimits& L, int a, int side, int b) {
  return link_axis_excess(side > 0 ? x - cn : cn - x, L, b == a);  // the link's + end minus its - end
}

/// The bound that neighbour n (displacement cn on axis b) puts on an element through their link:
/// the upper end of the link's interval (upper) or its lower end, as link_interval computes it
/// (the same floats as the propagation's clamp).
HPCM_HD inline float link_bound(float cn, const LinkLimits& L, int a, int side, int b, bool upper) {
  float lo, hi;
  link_interval(cn, L, b == a, side, lo, hi);
  return upper ? hi : lo;
}

/// One element of a pass: the coordinate moved to the bound when it lies beyond it.
HPCM_HD inline float restore_step(float x, float bound, bool upper) {
  if (upper) return bound < x ? bound : x;
  return bound > x ? bound : x;
}

}  // namespace hpcm::solver
