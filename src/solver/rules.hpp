#pragma once
// The per-element rules of HP-ChainMail (SPEC §4), written once and used by the CPU solver,
// the CUDA kernels and the tests, so every backend computes exactly the same thing.
//
// Order. Elements are ordered by the key (t, index): a neighbour n is "upstream" of a
// candidate time c of element e when (t_n, n) < (c, e). The index breaks ties so that
// every link has an upstream side, which makes the result independent of sweep order.
//
// Propagation rule. For each distinct candidate time c = t_n + w_link of a reached neighbour,
// in ascending order: clamp the wave-start position p0 into the intersection of the boxes
// of all upstream neighbours; the first c at which this moves the element gives its time and
// position. If none moves it, it keeps t = +inf and p0 (bit-identical). This is exactly what a
// Dijkstra-order sweep computes (src/solver/reference/dijkstra.cpp).
#include <cmath>

#include "hpcm/material.hpp"
#include "core/link_box.hpp"

namespace hpcm::solver {

inline constexpr float kInf = __builtin_huge_valf();
/// Relative gap below which two box limits count as touching (a few float ulps): tight links
/// produce boxes that meet in a point, and rounding must not turn that into a conflict.
inline constexpr float kGapTolerance = 4.0f * 1.1920929e-7f;

/// One neighbour of an element as the rules see it. Positions are displacements from rest
/// (u = X - X0, core/link_box.hpp).
struct Neighbour {
  Index idx;
  int axis;       ///< link axis
  int side;       ///< +1: element = neighbour + unit_axis at rest; -1: element = neighbour - unit_axis
  LinkLimits L;   ///< the link's limits
  float t;        ///< neighbour's arrival time
  float tau;      ///< neighbour's own tolerance (relaxation weight)
  Vec3 p;         ///< neighbour's displacement from rest
};

/// The boundary box every element stays inside, [-margin, N_axis - 1 + margin] on each axis
/// (the velocity layer's boundary clamp, SPEC §5.7). ChainMail treats it as one more box: the
/// wave, the relaxation and the link restoration never move an element out of it, so the
/// boundary clamp never has to collapse cells that ChainMail placed. make_wall gives it in
/// lattice coordinates; element_wall gives one element's displacement bounds.
struct Wall {
  float lo[3] = {-kInf, -kInf, -kInf};
  float hi[3] = {kInf, kInf, kInf};
};
inline Wall make_wall(Int3 dims, float margin) {
  Wall w;
  const int d[3] = {dims.x, dims.y, dims.z};
  for (int a = 0; a < 3; ++a) {
    w.lo[a] = -margin;
    w.hi[a] = static_cast<float>(d[a] - 1) + margin;
  }
  return w;
}

/// The wall as bounds on the displacement of the element at lattice (x, y, z):
/// u[a] in [wall.lo[a] - i_a, wall.hi[a] - i_a]. Every backend computes it with these two
/// float subtractions (the SIMD kernels lane by lane), so they all clamp to the same floats.
HPCM_HD inline float wall_lo_of(const Wall& w, int a, int i) { return w.lo[a] - static_cast<float>(i); }
HPCM_HD inline float wall_hi_of(const Wall& w, int a, int i) { return w.hi[a] - static_cast<float>(i); }
HPCM_HD inline Wall element_wall(const Wall& w, int x, int y, int z) {
  Wall e;
  const int c[3] = {x, y, z};
  for (int a = 0; a < 3; ++a) {
    e.lo[a] = wall_lo_of(w, a, c[a]);
    e.hi[a] = wall_hi_of(w, a, c[a]);
  }
  return e;
}

HPCM_HD inline bool key_less(float ta, Index ia, float tb, Index ib) { return ta < tb || (ta == tb && ia < ib); }

/// Clamps p0 (a displacement) into the intersection of the element's wall (element_wall) and the boxes of the neighbours in `mask`
/// (bit k = nb[k]). Where the intersection is empty on an axis, the earliest neighbour's box
/// (by key) is used, then the wall; a gap of a few ulps (rounding of boxes that touch) takes
/// the touching point instead. Without a neighbour in `mask`, p0 is returned unchanged.
HPCM_HD inline Vec3 clamp_into_boxes(Vec3 p0, const Neighbour* nb, int count, unsigned mask, const Wall& wall) {
  int first = -1;
  for (int k = 0; k < count; ++k)
    if ((mask >> k) & 1u)
      if (first < 0 || key_less(nb[k].t, nb[k].idx, nb[first].t, nb[first].idx)) first = k;
  Vec3 out = p0;
  if (first < 0) return out;
  for (int b = 0; b < 3; ++b) {
    float lo = wall.lo[b], hi = wall.hi[b];
    for (int k = 0; k < count; ++k)
      if ((mask >> k) & 1u) {
        float l, h;
        link_interval(nb[k].p, nb[k].L, nb[k].axis, nb[k].side, b, l, h);
        lo = lo > l ? lo : l;
        hi = hi < h ? hi : h;
      }
    if (lo > hi) {
      if (lo - hi <= kGapTolerance * (1.0f + (lo < 0 ? -lo : lo))) {
        // Only rounding separates the boxes (tight links meet at one point): take that point.
        out[b] = 0.5f * (lo + hi);
        continue;
      }
      // Truly conflicting boxes: the earliest neighbour wins (SPEC §4), inside the wall.
      link_interval(nb[first].p, nb[first].L, nb[first].axis, nb[first].side, b, lo, hi);
      out[b] = clampf(clampf(p0[b], lo, hi), wall.lo[b], wall.hi[b]);
      continue;
    }
    out[b] = clampf(p0[b], lo, hi);
  }
  return out;
}

/// Time bucket of t: floor(t / delta) with t promoted to double (the same test files and reads).
HPCM_HD inline unsigned long long bucket_of(float t, double delta) {
  return static_cast<unsigned long long>(floor(static_cast<double>(t) / delta));
}

/// The propagation rule restricted to the candidates of one time bucket (the schedule of
/// src/cpu/chainmail_propagate.cpp and the CUDA kernels): candidate times below the bucket were
/// decided in earlier buckets (their upstream sets can no longer change), candidates above it
/// belong to later buckets.
HPCM_HD inline bool propagate_in_bucket(long long e, Vec3 p0, const Neighbour* nb, int count,
                                        unsigned long long bucket, double delta, const Wall& wall, float& t_out,
                                        Vec3& p_out) {
  float cand[6];
  int nc = 0;
  for (int k = 0; k < count; ++k)
    if (nb[k].t < kInf) {
      const float c = nb[k].t + nb[k].L.w;
      if (bucket_of(c, delta) != bucket) continue;
      int j = nc++;
      while (j > 0 && cand[j - 1] > c) {
        cand[j] = cand[j - 1];
        --j;
      }
      cand[j] = c;
    }
  for (int i = 0; i < nc; ++i) {
    if (i > 0 && cand[i] == cand[i - 1]) continue;
    const float c = cand[i];
    unsigned mask = 0;
    for (int k = 0; k < count; ++k)
      if (key_less(nb[k].t, nb[k].idx, c, e)) mask |= 1u << k;
    const Vec3 p = clamp_into_boxes(p0, nb, count, mask, wall);
    if (!(p == p0)) {
      t_out = c;
      p_out = p;
      return true;
    }
  }
  t_out = kInf;
  p_out = p0;
  return false;
}

/// The relaxed coordinate: cur + omega * q, where q is the correction toward the weighted
/// average, rounded to nearest unless rounding lengthens the step to (2 + omega) / 2 times q or
/// more (halfway from the requested over-relaxation to the stability limit 2); then the float
/// next to it toward cur (nextafterf(t, cur)). Rounding a 1.85-times step of a few float steps
/// to the float grid could otherwise make it a 2-times step, a mirror image through the average
/// (2 ulps -> -2 ulps and back, for ever). With every applied step below 2 times q, each one
/// lowers the relaxation's energy, so the relaxation always comes to rest (docs/solver.md).
///
/// Written once over the lane type (core/lanes.hpp) and without a branch: a third to a half of
/// the SIMD kernel's vectors have a lane that steps back, a branch the CPU would mispredict that
/// often. The step back is one on the bit pattern: minus one where that moves toward zero, plus
/// one where it moves away; from t = 0 (reached only by a step of a few denormals that lands on
/// zero exactly) the float next to zero on cur's side. The AVX-512 kernels specialise it on mask
/// registers (cpu/simd_avx512.cpp, same bits: tests/solver/test_rules_once.cpp).
template <class T>
HPCM_HD inline T relax_coordinate(T cur, T q, T omega) {
  using I = lane_int_t<T>;
  const T zero = T{};
  const T t = cur + omega * q;
  const T d = t - cur;
  const T limit = (0.5f * (2.0f + omega)) * q;
  // A NaN fails every comparison: no step back.
  const auto back = (q > zero ? d >= limit : d <= limit) & (q != zero);
  const auto toward_zero = (t > cur) == (t > zero);
  const I bits = bit_pattern(t), one = I{} + 1, minus_one = I{} - 1;
  const I sign_of_cur = bit_pattern(cur) & (I{} + static_cast<std::int32_t>(0x80000000u));
  const I stepped = t == zero ? (sign_of_cur | one) : wrapping_add(bits, toward_zero ? minus_one : one);
  return from_bit_pattern<T>(back ? stepped : bits);
}

/// Whether the relaxation applies an element's step (SPEC §4, "Relaxation"): ChainMail's slack.
/// Near rest, within `slack` of it, a correction smaller than the threshold is skipped, so still
/// tissue stays still and a pull reaches only as far as its corrections are large (§8.8). An
/// element farther from rest than `slack` takes every correction: released tissue returns to
/// within the slack of rest instead of stopping wherever its corrections became small, and
/// tissue carried past rest by its velocity is pulled back (docs/solver.md, "Reach and slack").
/// Squared lengths, as squared_length_bound gives them; a zero step is never applied. On the
/// lane type T, as relax_coordinate.
template <class T>
HPCM_HD inline auto relax_step_applies(T step_sq, T threshold_sq, T displacement_sq, T slack_sq) {
  return ((step_sq >= threshold_sq) | (displacement_sq >= slack_sq)) & (step_sq != T{});
}

/// The least float s with sqrtf(s) >= length: a length compared as its square gives the same
/// outcome as the length itself (sqrtf is correctly rounded, hence monotone). 0 for a length
/// <= 0; +infinity stays +infinity. Host code: the backends compute it once per relaxation.
inline float squared_length_bound(float length) {
  if (!(length > 0.0f)) return 0.0f;
  float s = length * length;
  while (std::sqrt(s) < length) s = std::nextafter(s, kInf);
  while (s > 0.0f && std::sqrt(std::nextafter(s, 0.0f)) >= length) s = std::nextafter(s, 0.0f);
  return s;
}

/// A relaxation weight: 1 / (tau + 1e-4) for a neighbour of tolerance tau (relax_element; the
/// CPU storage holds it per element).
template <class T>
HPCM_HD inline T relax_weight(T tau) {
  return 1.0f / (tau + 1e-4f);
}

/// The relaxation's weighted sum of the neighbours' proposals, as offsets from the element
/// (relax_element): add() once per neighbour in the rule's order -x, +x, -y, +y, -z, +z, then
/// target() per axis. On the lane type T, as relax_coordinate.
template <class T>
struct ProposalSum {
  T s[3] = {T{}, T{}, T{}};
  T sw = T{};
  /// A neighbour of weight w whose proposal lies at offset o from the element.
  HPCM_HD void add(T w, T o0, T o1, T o2) {
    s[0] = s[0] + w * o0;
    s[1] = s[1] + w * o1;
    s[2] = s[2] + w * o2;
    sw = sw + w;
  }
  /// The relaxed coordinate b of an element at cur (relax_coordinate with q = s[b] / sw).
  HPCM_HD T target(int b, T cur, T omega) const { return relax_coordinate(cur, s[b] / sw, omega); }
};

/// Relaxation rule: (over-relaxed step toward the) weighted average of the neighbours'
/// proposals (their displacements u_n: a neighbour proposes that the element be displaced as it
/// is) with weight 1/(tau_n + 1e-4), then clamped into all neighbours' boxes and the element's
/// wall `wall` (element_wall; never creates a violation against the neighbours' current
/// positions). `omega` over-relaxes the step from the current displacement `cur` toward the
/// average (successive over-relaxation; omega = 1 is plain Gauss-Seidel).
///
/// The average is taken of the proposals' offsets from `cur` (u_n - cur), not of the proposals:
/// the same number in exact arithmetic, but the offsets are small and u_n - cur is exact, so the
/// step is exact to a few ulps of itself; the new displacement never becomes a 2-times step by
/// rounding (relax_coordinate). docs/solver.md, "Relaxation arithmetic".
HPCM_HD inline Vec3 relax_element(const Neighbour* nb, int count, Vec3 cur, float omega, const Wall& wall) {
  ProposalSum<float> sum;
  for (int k = 0; k < count; ++k) {
    const Vec3 off = nb[k].p - cur;
    sum.add(relax_weight(nb[k].tau), off.x, off.y, off.z);
  }
  const Vec3 target{sum.target(0, cur.x, omega), sum.target(1, cur.y, omega), sum.target(2, cur.z, omega)};
  return clamp_into_boxes(target, nb, count, (1u << count) - 1u, wall);
}

}  // namespace hpcm::solver
