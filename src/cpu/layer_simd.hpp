#pragma once
// The velocity layer over one row, N elements at a time (through kernel_table.hpp, in each
// simd_*.cpp). Lane by lane these are the floating-point operations of
// dynamics::velocity_update in the same order, with its branches as lane masks: FIXED,
// massless or condition A; the dead zone on |dX|; simple or viscoelastic update; the magnitude
// clamp or the rest threshold; the position step; the boundary clamp (on displacements from
// rest: the element's own bounds, lattice coordinates minus X0). The speeds for the
// report are then added in element order, so every path gives the same sums.
#include <cmath>

#include "cpu/kernels.hpp"
#include "cpu/simd.hpp"
#include "hpcm/state.hpp"

namespace hpcm::cpu::simd {

/// Per-lane value of a per-tissue constant (t in 0..3).
template <class V>
inline V by_tissue(Mask<V> t, const float (&c)[4]) {
  return t == 0 ? splat<V>(c[0]) : (t == 1 ? splat<V>(c[1]) : (t == 2 ? splat<V>(c[2]) : splat<V>(c[3])));
}

template <class V>
inline V norm3(V a, V b, V c) {
  return vsqrt<V>(a * a + b * b + c * c);
}

template <class V>
void layer_row(Storage& st, const dynamics::LayerConstants& k, const LayerRow& r, SpeedStats* speeds) {
  constexpr int N = sizeof(V) / sizeof(float);
  using M = Mask<V>;
  const Layout& L = st.lay;
  const Index k0 = L.row_start(r.h, r.y, r.z);
  const V zero = splat<V>(0.0f);
  const V fy = splat<V>(static_cast<float>(r.y)), fz = splat<V>(static_cast<float>(r.z));
  const V alpha = splat<V>(k.alpha), one_b0 = splat<V>(1.0f + k.b0), dead_zone = splat<V>(k.dead_zone);
  const V v_max = splat<V>(k.v_max), beta = splat<V>(k.beta);
  V lane;
  for (int l = 0; l < N; ++l) lane[l] = static_cast<float>(l);
  // Brick columns are col_width (a power of two) row elements wide: shifts, not divisions.
  int col_shift = 0;
  while ((1 << col_shift) < r.col_width) ++col_shift;
  // Pointers in locals: the byte stores of the column flags may alias any memory, and would
  // otherwise make the compiler reload them for every vector.
  const int col_base = r.col_base;
  auto column = [col_base, col_shift](int jl) { return (jl - col_base) >> col_shift; };
  float* p_[3] = {st.p[0].data(), st.p[1].data(), st.p[2].data()};
  float* q_[3] = {st.q[0].data(), st.q[1].data(), st.q[2].data()};
  float* v_[3] = {st.v[0].data(), st.v[1].data(), st.v[2].data()};
  const std::uint8_t* const tissue = st.tissue.data();
  const std::uint8_t* const stat_class = st.stat_class.data();
  const std::uint8_t* const flags = st.flags.data();
  const std::uint8_t* const col_asleep = r.col_asleep;
  std::uint8_t* const col_velocity = r.col_velocity;
  std::uint8_t* const col_moved = r.col_moved;
  float* const col_speed = r.col_speed;
  for (int j = r.j0; j < r.j1; j += N) {
    const Index e = k0 + j;
    const int count = std::min(N, r.j1 - j);
    const M in_row = lane < splat<V>(static_cast<float>(count));
    const M t = load_bytes<V>(tissue + e);
    M fixed = (load_bytes<V>(flags + e) & static_cast<int>(kFixed)) != 0;
    bool any_asleep = false;  // a sleeping brick's elements get no dynamics this frame
    for (int c = column(j); c <= column(j + count - 1); ++c) any_asleep |= col_asleep[c] != 0;
    if (any_asleep)
      for (int l = 0; l < count; ++l)
        if (col_asleep[column(j + l)]) fixed[l] = -1;
    V post[3], pre[3], v[3];
    if (prefetch_due<N>(j)) {  // nine streams; 4 lines ahead measured best (BENCHMARKS.md)
      constexpr int kAhead = 4 * kPrefetchLine;
      for (int a = 0; a < 3; ++a) {
        prefetch(p_[a] + e + kAhead);
        prefetch(q_[a] + e + kAhead);
        prefetch(v_[a] + e + kAhead);
      }
      // The tissue and flag bytes, as far ahead in lines: four times as many elements.
      prefetch(tissue + e + 4 * kAhead);
      prefetch(flags + e + 4 * kAhead);
    }
    for (int a = 0; a < 3; ++a) {
      post[a] = load<V>(p_[a] + e);
      pre[a] = load<V>(q_[a] + e);
      v[a] = load<V>(v_[a] + e);
    }
    // 1. FIXED / massless (bone), and condition A: no dynamics.
    const M dynamic = ~fixed & (by_tissue<V>(t, k.inv_mass) != zero) & (k.mode != 0 ? M{} - 1 : M{});
    // 2. intra-frame ChainMail correction, with its dead zone.
    V dx[3];
    for (int a = 0; a < 3; ++a) dx[a] = post[a] - pre[a];
    const M dead = norm3<V>(dx[0], dx[1], dx[2]) < dead_zone;
    for (int a = 0; a < 3; ++a) dx[a] = dead ? zero : dx[a];
    const V s = by_tissue<V>(t, k.s);  // 3. response scale
    V nv[3];
    if (k.mode == 1) {  // 4. simple (B)
      for (int a = 0; a < 3; ++a) nv[a] = alpha * v[a] + s * dx[a];
    } else {  // viscoelastic (C)
      V vt[3];
      for (int a = 0; a < 3; ++a) vt[a] = v[a] + s * dx[a];
      const V denom = one_b0 + by_tissue<V>(t, k.b1) * norm3<V>(pre[0], pre[1], pre[2]);  // |X- - X0|
      for (int a = 0; a < 3; ++a) nv[a] = vt[a] / denom;
    }
    // 5. magnitude clamp keeping the direction.
    const V speed = norm3<V>(nv[0], nv[1], nv[2]);
    const M fast = speed > v_max;
    const V f = v_max / speed;
    for (int a = 0; a < 3; ++a) nv[a] = fast ? nv[a] * f : nv[a];
    // The column maxima of the speeds of the dynamic lanes (speeds are >= 0: the other lanes
    // enter as 0 and change no maximum).
    const M dynamic_in_row = dynamic & in_row;
    const V speed_dynamic = dynamic_in_row ? speed : zero;
    const int width = 1 << col_shift;
    if (count == N && ((j - col_base) & (width - 1)) == 0 && width <= N) {
      // A whole vector of whole columns: every column's maximum, without a branch on which
      // lanes are dynamic (on a CT they are scattered); a column without one takes max(m, 0).
      float* const c0 = col_speed + ((j - col_base) >> col_shift);
      for (int c = 0; c < N >> col_shift; ++c) {
        float m = c0[c];
        for (int l = c * width; l < (c + 1) * width; ++l) m = m > speed_dynamic[l] ? m : speed_dynamic[l];
        c0[c] = m;
      }
    } else {
      for_each_column(lane_bits<V>(dynamic_in_row), j - col_base, col_shift, N, [&](int c, unsigned lanes) {
        float m = col_speed[c];
        for (int l = __builtin_ctz(lanes), last = 31 - __builtin_clz(lanes); l <= last; ++l)
          m = m > speed_dynamic[l] ? m : speed_dynamic[l];
        col_speed[c] = m;
      });
    }
    // 6. position update.
    const V g = beta * by_tissue<V>(t, k.rho);
    V out[3];
    const V fx = splat<V>(static_cast<float>(r.h)) + splat<V>(2.0f) * (lane + splat<V>(static_cast<float>(j)));
    const V rest[3] = {fx, fy, fz};
    for (int a = 0; a < 3; ++a) {
      nv[a] = dynamic ? nv[a] : zero;
      const V x = dynamic ? post[a] + g * nv[a] : post[a];
      // 7. boundary clamp, on u: k.lo - X0, k.hi - X0 (dynamics::velocity_update).
      const V lo = splat<V>(k.lo[a]) - rest[a], hi = splat<V>(k.hi[a]) - rest[a];
      out[a] = x < lo ? lo : (x > hi ? hi : x);
    }
    if (count == N) {
      for (int a = 0; a < 3; ++a) {
        store<V>(v_[a] + e, nv[a]);
        store<V>(p_[a] + e, out[a]);
        store<V>(q_[a] + e, out[a]);  // frame-end snapshot: next frame's X-
      }
    } else {  // the row's last vector: lanes past it are not this row's
      const unsigned row_lanes = (1u << count) - 1u;
      for (int a = 0; a < 3; ++a) {
        store_lanes<V>(v_[a] + e, nv[a], row_lanes);
        store_lanes<V>(p_[a] + e, out[a], row_lanes);
        store_lanes<V>(q_[a] + e, out[a], row_lanes);
      }
    }
    const M has_v = (nv[0] != zero) | (nv[1] != zero) | (nv[2] != zero);
    const M changed = (out[0] != post[0]) | (out[1] != post[1]) | (out[2] != post[2]);
    const unsigned with_v = lane_bits<V>(has_v & in_row), moved = lane_bits<V>(changed & in_row);
    mark_columns(with_v, j - col_base, col_shift, N, col_velocity, count == N);
    mark_columns(moved, j - col_base, col_shift, N, col_moved, count == N);
    if (speeds) {
      const V sp = norm3<V>(out[0] - pre[0], out[1] - pre[1], out[2] - pre[2]);
      for (int l = 0; l < count; ++l) {
        if (sp[l] > 0) ++speeds->moved;
        const int c = stat_class[e + l];
        if (c == kTissueCount) continue;  // outside the body: not in the statistics (SPEC §3)
        speeds->sum[c] += sp[l];
        speeds->max[c] = std::max(speeds->max[c], sp[l]);
      }
    }
  }
}

}  // namespace hpcm::cpu::simd
