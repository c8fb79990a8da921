#pragma once
// Gibson's deformation box of one link (SPEC §4), part of the model: shared by the solver
// rules, both backends, the references and the metrics, so that every component tests the
// same constraint.
#include "hpcm/material.hpp"
#include "hpcm/types.hpp"

namespace hpcm {

// Everything here works on displacements from rest, u = X - X0 (lattice units): a link from n to
// e = n + unit_a is in its box when u_e[a] - u_n[a] lies in [min_stretch, max_stretch] and
// |u_e[b] - u_n[b]| <= shear across it. Displacements stay small wherever the element sits, so
// their float step (and every rounding of these limits) does not grow with the lattice.

/// Interval on axis b allowed for the displacement of element e by neighbour n (displacement
/// un), where the link lies along axis a and side = +1 if e = n + unit_a at rest, -1 if
/// e = n - unit_a.
HPCM_HD inline void link_interval(const Vec3& un, const LinkLimits& L, int a, int side, int b, float& lo, float& hi) {
  const float c = un[b];
  if (b == a) {
    if (side > 0) {
      lo = c + L.min_stretch;
      hi = c + L.max_stretch;
    } else {
      lo = c - L.max_stretch;
      hi = c - L.min_stretch;
    }
  } else {
    lo = c - L.shear;
    hi = c + L.shear;
  }
}

/// How far one displacement difference of a link (its + end minus its - end) lies outside the
/// box on that axis: [min_stretch, max_stretch] along the link (`axial`), |d| <= shear across it
/// (0 inside).
HPCM_HD inline float link_axis_excess(float d, const LinkLimits& L, bool axial) {
  if (axial) return d < L.min_stretch ? L.min_stretch - d : (d > L.max_stretch ? d - L.max_stretch : 0.0f);
  const float ad = d < 0 ? -d : d;
  return ad > L.shear ? ad - L.shear : 0.0f;
}

/// How far the link (lo_elem with displacement u_lo, hi_elem = lo_elem + unit_a with u_hi) is
/// outside its box.
HPCM_HD inline float link_violation(const Vec3& u_lo, const Vec3& u_hi, const LinkLimits& L, int a) {
  float v = 0.0f;
  for (int b = 0; b < 3; ++b) {
    const float e = link_axis_excess(u_hi[b] - u_lo[b], L, b == a);
    v = e > v ? e : v;
  }
  return v;
}

HPCM_HD inline float clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }

}  // namespace hpcm
