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
// direction. The midpoint is rounded, which can leave a link a float step and a half outside its
// box, so a last lower and raise pass from the midpoints brings every link back to within the
// rounding of one bound (half a float step).
// Each pass is a monotone fixed-point iteration, so its result does not depend on the order in
// which elements are visited: any schedule (sequential work list, parallel chaotic sweeps on
// the GPU) gives the same floats.
#include "core/link_box.hpp"
#include "solver/rules.hpp"

namespace hpcm::solver {

/// Links (and boundary-box excursions) beyond this are restored. Well below the 1e-5 of the
/// integrity check, above the rounding of the clamps themselves (half an ulp of a coordinate
/// below 128 is at most 3.8e-6), so a restored link is not found violated again.
inline constexpr float kRestoreTolerance = 4e-6f;

/// The bound that neighbour n (coordinate cn on axis b) puts on an element through their link:
/// the upper end of the link's interval (upper) or its lower end. Same floats as link_interval,
/// so the propagation's clamp and the restoration agree on every box. Rounded to nearest, so a
/// pass leaves a link at most half a float step outside its box (3.8e-6 below coordinate 128,
/// 7.6e-6 below 256). Rounding toward the inside of the box was tried: at the tool limit the
/// chain of links between the tool and an anchor is stretched exactly to its slack, and boxes
/// tightened by a float step each can no longer all be met (3.1e-5 measured on the DICOM
/// series at downsample 2).
HPCM_HD inline float link_bound(float cn, const LinkLimits& L, int a, int side, int b, bool upper) {
  Vec3 pn{};
  pn[b] = cn;
  float lo, hi;
  link_interval(pn, L, a, side, b, lo, hi);
  return upper ? hi : lo;
}

/// One element of a pass: the coordinate moved to the bound when it lies beyond it.
HPCM_HD inline float restore_step(float x, float bound, bool upper) {
  if (upper) return bound < x ? bound : x;
  return bound > x ? bound : x;
}

}  // namespace hpcm::solver
