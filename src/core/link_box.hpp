#pragma once
// Gibson's deformation box of one link (SPEC §4), part of the model: shared by the solver
// rules, both backends, the references and the metrics, so that every component tests the
// same constraint.
#include "hpcm/material.hpp"
#include "hpcm/types.hpp"

namespace hpcm {

/// Interval on axis b allowed for element e by neighbour n at position pn, where the link
/// lies along axis a and side = +1 if e = n + unit_a at rest, -1 if e = n - unit_a.
HPCM_HD inline void link_interval(const Vec3& pn, const LinkLimits& L, int a, int side, int b, float& lo, float& hi) {
  const float c = pn[b];
  if (b == a) {
    if (side > 0) {
      lo = c + L.min_d;
      hi = c + L.max_d;
    } else {
      lo = c - L.max_d;
      hi = c - L.min_d;
    }
  } else {
    lo = c - L.shear;
    hi = c + L.shear;
  }
}

/// How far one coordinate difference of a link (its + end minus its - end) lies outside the
/// box on that axis: [min_d, max_d] along the link (`axial`), |d| <= shear across it (0 inside).
HPCM_HD inline float link_axis_excess(float d, const LinkLimits& L, bool axial) {
  if (axial) return d < L.min_d ? L.min_d - d : (d > L.max_d ? d - L.max_d : 0.0f);
  const float ad = d < 0 ? -d : d;
  return ad > L.shear ? ad - L.shear : 0.0f;
}

/// How far the link (lo_elem at p_lo, hi_elem = lo_elem + unit_a at p_hi) is outside its box.
HPCM_HD inline float link_violation(const Vec3& p_lo, const Vec3& p_hi, const LinkLimits& L, int a) {
  float v = 0.0f;
  for (int b = 0; b < 3; ++b) {
    const float e = link_axis_excess(p_hi[b] - p_lo[b], L, b == a);
    v = e > v ? e : v;
  }
  return v;
}

HPCM_HD inline float clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }

}  // namespace hpcm
