#pragma once
// Gibson's deformation box of one link (SPEC §4), part of the model: shared by the solver
// rules, both backends, the references and the metrics, so that every component tests the
// same constraint.
#include "core/lanes.hpp"
#include "hpcm/material.hpp"
#include "hpcm/types.hpp"

namespace hpcm {

// Everything here works on displacements from rest, u = X - X0 (lattice units): a link from n to
// e = n + unit_a is in its box when u_e[a] - u_n[a] lies in [min_stretch, max_stretch] and
// |u_e[b] - u_n[b]| <= shear across it. Displacements stay small wherever the element sits, so
// their float step (and every rounding of these limits) does not grow with the lattice.

// Each rule is written once over the lane type T (core/lanes.hpp): float in host and device
// code, a GCC vector of floats in the CPU's SIMD kernels (cpu/relax_simd.hpp,
// cpu/link_check_simd.hpp), with `Box` a LinkLimits or a LinkBox<T> (hpcm/material.hpp). The
// Vec3 forms below are the float rules on one element. tests/solver/test_rules_once.cpp holds
// every SIMD width to the float instantiation bit for bit.

/// Interval [lo, hi] allowed for coordinate b of the displacement of element e by neighbour n,
/// whose displacement on that axis is c: along the link (`axial`: b is the link's axis a),
/// side = +1 if e = n + unit_a at rest, -1 if e = n - unit_a; across it, c -+ shear.
template <class T, class Box>
HPCM_HD inline void link_interval(T c, const Box& L, bool axial, int side, T& lo, T& hi) {
  if (axial) {
    if (side > 0) {
      lo = add_exact(c, L.min_stretch);
      hi = add_exact(c, L.max_stretch);
    } else {
      lo = sub_exact(c, L.max_stretch);
      hi = sub_exact(c, L.min_stretch);
    }
  } else {
    lo = sub_exact(c, L.shear);
    hi = add_exact(c, L.shear);
  }
}

/// link_interval on axis b for the link along axis a, the neighbour at displacement un.
HPCM_HD inline void link_interval(const Vec3& un, const LinkLimits& L, int a, int side, int b, float& lo, float& hi) {
  link_interval(un[b], L, b == a, side, lo, hi);
}

/// How far one displacement difference d of a link (its + end minus its - end) lies beyond the
/// box on that axis, signed: positive outside, <= 0 inside, NaN where d is. Along the link
/// (`axial`) the larger of min_stretch - d and d - max_stretch; across it |d| - shear. A
/// difference x - y of floats is > 0 exactly when x > y (gradual underflow), so this is positive
/// exactly where d is outside the box.
template <class T, class Box>
HPCM_HD inline T link_axis_overshoot(T d, const Box& L, bool axial) {
  if (axial) {
    const T below = L.min_stretch - d, above = d - L.max_stretch;
    return below > above ? below : above;
  }
  const T minus_d = -d;
  return (d > minus_d ? d : minus_d) - L.shear;
}

/// How far one displacement difference of a link lies outside the box on that axis:
/// [min_stretch, max_stretch] along the link (`axial`), |d| <= shear across it (0 inside).
template <class T, class Box>
HPCM_HD inline T link_axis_excess(T d, const Box& L, bool axial) {
  const T e = link_axis_overshoot(d, L, axial), zero = T{};
  return e > zero ? e : zero;
}

/// How far a link along axis a is outside its box: the largest link_axis_excess over the axes,
/// d[b] its + end's displacement minus its - end's on axis b (0 inside; a NaN difference counts
/// as inside, as in link_axis_excess).
template <class T, class Box>
HPCM_HD inline T link_violation(const T (&d)[3], const Box& L, int a) {
  T v = T{};
  for (int b = 0; b < 3; ++b) {
    const T e = link_axis_overshoot(d[b], L, b == a);
    v = e > v ? e : v;
  }
  return v;
}

/// How far the link (lo_elem with displacement u_lo, hi_elem = lo_elem + unit_a with u_hi) is
/// outside its box.
HPCM_HD inline float link_violation(const Vec3& u_lo, const Vec3& u_hi, const LinkLimits& L, int a) {
  const float d[3] = {u_hi.x - u_lo.x, u_hi.y - u_lo.y, u_hi.z - u_lo.z};
  return link_violation(d, L, a);
}

HPCM_HD inline float clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }

}  // namespace hpcm
