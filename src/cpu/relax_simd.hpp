#pragma once
// The relaxation rule over a run of one colour, N elements at a time (included by
// relax_simd_sse2.cpp with 4-wide and by relax_simd_avx2.cpp with 8-wide vectors; each file is
// compiled for its instruction set). Lane by lane these are the floating-point operations of
// relax_element_scalar in the same order: weights times proposals summed over the neighbours
// -x, +x, -y, +y, -z, +z from zero, the box limits rebuilt from the link's tolerance exactly as
// limits_from_tau does, max/min for the intersection, one IEEE division, the over-relaxed step
// and the clamp. No fused multiply-add (the build uses -ffp-contract=off, and the AVX2 file
// does not enable FMA). Lanes whose boxes do not intersect, and the border elements of the
// lattice, go to the scalar rule. The last vector of a run is masked; its loads may run past
// the run into the storage's padding.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "cpu/relax.hpp"
#include "cpu/simd.hpp"
#include "hpcm/state.hpp"

namespace hpcm::cpu::simd {

template <class V>
float relax_run(const RelaxContext& c, const RelaxRun& r) {
  constexpr int N = sizeof(V) / sizeof(float);
  using M = Mask<V>;
  const Layout& L = *c.lay;
  const int nx = L.dims.x, ny = L.dims.y, nz = L.dims.z;
  const int h = r.h;
  float max_corr = 0.0f;
  auto mark = [&](int j) { r.col_changed[(j - r.col_base) / r.col_width] = 1; };
  auto scalar = [&](int j) {
    const float corr = relax_element_scalar(c, 2 * j + h, r.y, r.z);
    if (corr > 0.0f) {
      mark(j);
      max_corr = std::max(max_corr, corr);
    }
  };
  // Elements with both x neighbours: 1 <= x <= nx - 2 with x = 2j + h. A row lacks its -y, +y,
  // -z or +z neighbours all along, so the vector code simply leaves those out, as the scalar
  // rule does; the elements at the two ends of the row take the scalar rule.
  // A row lacks its -y, +y, -z or +z neighbours all along, and its first and last element lack
  // a -x or +x neighbour: the vector code leaves a missing neighbour out (weight 0 and an
  // unbounded box, which adds exactly nothing to the sums and limits), as the scalar rule does.
  const int i0 = r.j0, i1 = r.j1;
  const bool present[6] = {true, true, r.y > 0, r.y + 1 < ny, r.z > 0, r.z + 1 < nz};
  const V minus_inf = splat<V>(-solver::kInf), plus_inf = splat<V>(solver::kInf);
  const Index own0 = L.row_start(h, r.y, r.z);
  const Index oth0 = L.row_start(1 - h, r.y, r.z);
  const Index sy = L.width[h], sz = static_cast<Index>(L.width[h]) * ny;
  // -x neighbour of element j: other half, index j - 1 (h = 0) or j (h = 1); +x: j or j + 1.
  const Index left = oth0 - (h == 0 ? 1 : 0), right = oth0 + (h == 0 ? 0 : 1);
  const V one = splat<V>(1.0f), zero = splat<V>(0.0f);
  const V k08 = splat<V>(0.8f), k098 = splat<V>(0.98f), khalf = splat<V>(0.5f);
  const V omega = splat<V>(c.omega), threshold = splat<V>(c.threshold);
  const bool plain = c.omega == 1.0f;
  V lane_index;
  for (int l = 0; l < N; ++l) lane_index[l] = static_cast<float>(l);

  for (int j = i0; j < i1; j += N) {
    const Index k = own0 + j;
    // Neighbour storage indices (first lane), link owners, axis and side, in the rule's order.
    const Index nk[6] = {left + j, right + j, k - sy, k + sy, k - sz, k + sz};
    const Index owner[6] = {left + j, k, k - sy, k, k - sz, k};
    const int axis[6] = {0, 0, 1, 1, 2, 2};
    const float side[6] = {1.0f, -1.0f, 1.0f, -1.0f, 1.0f, -1.0f};
    V s[3] = {zero, zero, zero}, sw = zero;
    V lo[3] = {splat<V>(c.wall.lo[0]), splat<V>(c.wall.lo[1]), splat<V>(c.wall.lo[2])};
    V hi[3] = {splat<V>(c.wall.hi[0]), splat<V>(c.wall.hi[1]), splat<V>(c.wall.hi[2])};
    // Lanes whose element has no -x (x = 0) or no +x (x = nx - 1) neighbour.
    const V x = splat<V>(static_cast<float>(h)) + splat<V>(2.0f) * (lane_index + splat<V>(static_cast<float>(j)));
    const M no_left = x == splat<V>(0.0f), no_right = x == splat<V>(static_cast<float>(nx - 1));
    for (int q = 0; q < 6; ++q) {
      if (!present[q]) continue;
      const int a = axis[q];
      const M missing = q == 0 ? no_left : (q == 1 ? no_right : M{});
      const V w = missing ? splat<V>(0.0f) : load<V>(c.weight + nk[q]);
      V pn[3];
      for (int b = 0; b < 3; ++b) pn[b] = load<V>(c.p[b] + nk[q]);
      for (int b = 0; b < 3; ++b) s[b] = s[b] + w * (b == a ? pn[b] + side[q] : pn[b]);
      sw = sw + w;
      // limits_from_tau: min_d = 1 - 0.8 tau, max_d = 1 + tau, shear = min(tau, 0.5 (0.98 - 0.8 tau)).
      const V tau = load<V>(c.link_tau[a] + owner[q]);
      const V min_d = one - k08 * tau, max_d = one + tau;
      const V cap = khalf * (k098 - k08 * tau);
      const V shear = tau < cap ? tau : cap;
      for (int b = 0; b < 3; ++b) {
        V l, u;
        if (b == a) {
          l = side[q] > 0 ? pn[b] + min_d : pn[b] - max_d;
          u = side[q] > 0 ? pn[b] + max_d : pn[b] - min_d;
        } else {
          l = pn[b] - shear;
          u = pn[b] + shear;
        }
        lo[b] = vmax(lo[b], missing ? minus_inf : l);
        hi[b] = vmin(hi[b], missing ? plus_inf : u);
      }
    }
    const V cur[3] = {load<V>(c.p[0] + k), load<V>(c.p[1] + k), load<V>(c.p[2] + k)};
    V out[3];
    for (int b = 0; b < 3; ++b) {
      const V avg = s[b] / sw;
      const V target = plain ? avg : cur[b] + omega * (avg - cur[b]);
      out[b] = vmax(lo[b], vmin(hi[b], target));  // clampf, valid where lo <= hi
    }
    const V d0 = out[0] - cur[0], d1 = out[1] - cur[1], d2 = out[2] - cur[2];
    const V corr = vsqrt<V>(d0 * d0 + d1 * d1 + d2 * d2);
    const M in_run = lane_index < splat<V>(static_cast<float>(i1 - j));
    const M boxes_meet = ~(lo[0] > hi[0]) & ~(lo[1] > hi[1]) & ~(lo[2] > hi[2]);
    const M free = ((load_bytes<V>(c.flags + k) & static_cast<int>(kFixed)) == 0) & in_run;
    const M apply = boxes_meet & free & (corr >= threshold) & (corr != zero);
    const unsigned applied = lane_bits<V>(apply), conflict = lane_bits<V>(free & ~boxes_meet);
    if (applied) {
      if (j + N <= i1) {  // a full vector: every lane is this run's
        for (int b = 0; b < 3; ++b) store<V>(c.p[b] + k, apply ? out[b] : cur[b]);
      } else {  // the masked tail: lanes past the run may belong to another thread's run
        for (int l = 0; l < N; ++l)
          if (applied >> l & 1u)
            for (int b = 0; b < 3; ++b) c.p[b][k + l] = out[b][l];
      }
      for (int l = 0; l < N; ++l)
        if (applied >> l & 1u) {
          mark(j + l);
          max_corr = std::max(max_corr, corr[l]);
        }
    }
    if (conflict)
      for (int l = 0; l < N; ++l)
        if (conflict >> l & 1u) scalar(j + l);
  }
  return max_corr;
}

}  // namespace hpcm::cpu::simd
