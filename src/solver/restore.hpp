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
// lower and raise pass from the midpoints puts every link back: within half a float step of a
// coordinate below 128 (the bounds rounded to nearest), exactly inside its box on axes that
// reach further (the bounds rounded toward the inside, link_bound). On those axes a link whose
// ends the restoration has not moved is left as the stage placed it while it is within the
// tolerance (left_as_placed): the passes act only on the links the check found and on those
// around the elements they move.
// Each pass is a monotone fixed-point iteration, so its result does not depend on the order in
// which elements are visited: any schedule (sequential work list, parallel chaotic sweeps on
// the GPU) gives the same floats.
#include "core/link_box.hpp"
#include "solver/rules.hpp"

namespace hpcm::solver {

/// Links (and boundary-box excursions) beyond this are restored. Well below the 1e-5 of the
/// integrity check; above half a float step of a coordinate below 128 (3.8e-6), so the rounding
/// of the clamps does not call the restoration there (nor finds a restored link violated again).
/// Further out it does, and the restoration leaves those links exactly in their boxes.
inline constexpr float kRestoreTolerance = 4e-6f;

/// Whether coordinate x of element e on axis b keeps e's link to neighbour n (coordinate cn on
/// that axis) inside the link's box, by the same float arithmetic as link_violation.
HPCM_HD inline bool link_holds(float x, float cn, const LinkLimits& L, int a, int side, int b) {
  if (b != a) {
    const float d = x - cn;
    return (d < 0 ? -d : d) <= L.shear;
  }
  const float d = side > 0 ? x - cn : cn - x;  // the link's + end minus its - end
  return d >= L.min_d && d <= L.max_d;
}

/// How far coordinate x of element e on axis b lies outside the interval its link to neighbour n
/// (coordinate cn on that axis) allows, by the same float arithmetic as link_violation (0 inside).
HPCM_HD inline float link_excess(float x, float cn, const LinkLimits& L, int a, int side, int b) {
  return link_axis_excess(side > 0 ? x - cn : cn - x, L, b == a);  // the link's + end minus its - end
}

/// Whether a pass leaves the link between e (coordinate x) and n (cn) as the stage placed it:
/// on an axis that rounds inward, while neither end has moved in this restoration (e_moved,
/// n_moved: changed by any pass on this axis so far) and the link is within kRestoreTolerance.
/// The passes hold every link they act on exactly inside its box, more strictly than the check
/// that chose the seeds (kRestoreTolerance): links the stage left up to that far outside (half a
/// float step of a coordinate below 128) would otherwise be "restored" too, and where such a
/// link sits in a chain stretched to its slack between a moved element and a FIXED one, the last
/// one-sided pass pushed the chain into the FIXED element's box (1.7e-5 outside on the DICOM
/// series at f = 2, docs/solver.md). Links with a moved end are always held exactly, so a pass
/// still leaves every link it moves an element of exactly inside its box. "Moved" only ever
/// turns on during a pass and only adds bounds, so a pass stays a monotone fixed-point iteration.
HPCM_HD inline bool left_as_placed(bool e_moved, bool n_moved, float x, float cn, const LinkLimits& L, int a, int side,
                                   int b, bool inward) {
  return inward && !e_moved && !n_moved && link_excess(x, cn, L, a, side, b) <= kRestoreTolerance;
}

/// One float step above coordinate c >= 0 (NaN for an infinite c).
HPCM_HD inline float float_step_above(float c) { return nextafterf(c, INFINITY) - c; }

/// Whether the restoration rounds the box limits on an axis whose coordinates reach `largest`
/// (in magnitude) toward the inside of the box. Rounded to nearest, a limit can lie half a float
/// step outside the box: at most 3.8e-6 below coordinate 128, within the restoration's tolerance,
/// so those axes keep the nearest rounding the propagation and the relaxation use; from 128 on
/// (7.6e-6, 1.5e-5 beyond 256) a restored link could stay beyond the tolerance or the integrity
/// check's 1e-5, so those axes round inward. An unbounded axis rounds inward.
HPCM_HD inline bool rounds_inward(float largest) { return !(0.5f * float_step_above(largest) <= kRestoreTolerance); }

/// The bound that neighbour n (coordinate cn on axis b) puts on an element through their link:
/// the upper end of the link's interval (upper) or its lower end, as link_interval computes it
/// (the same floats as the propagation's clamp). With `inward`, it is then moved a float step at
/// a time toward the inside of the box until the link check itself holds there, so a pass leaves
/// every link it touches exactly inside its box, however far from the origin. Tightening a box
/// by up to a float step is what lets that fail at the tool limit, where the chain between the
/// tool and an anchor is stretched to its slack: the tool limit reserves two float steps per
/// link on such axes for it (solver/tool_limit.cpp).
HPCM_HD inline float link_bound(float cn, const LinkLimits& L, int a, int side, int b, bool upper, bool inward) {
  Vec3 pn{};
  pn[b] = cn;
  float lo, hi;
  link_interval(pn, L, a, side, b, lo, hi);
  float bound = upper ? hi : lo;
  // Rounded to nearest, the bound is at most half a float step outside (one step inward suffices;
  // the loop allows for an inexact subtraction where cn and the bound differ in magnitude).
  if (inward)
    for (int k = 0; k < 4 && !link_holds(bound, cn, L, a, side, b); ++k) bound = nextafterf(bound, upper ? -INFINITY : INFINITY);
  return bound;
}

/// One element of a pass: the coordinate moved to the bound when it lies beyond it.
HPCM_HD inline float restore_step(float x, float bound, bool upper) {
  if (upper) return bound < x ? bound : x;
  return bound > x ? bound : x;
}

}  // namespace hpcm::solver
