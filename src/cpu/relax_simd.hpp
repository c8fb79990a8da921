#pragma once
// The relaxation rule over a run of one colour, N elements at a time (through kernel_table.hpp,
// in simd_sse2.cpp, simd_avx2.cpp and simd_avx512.cpp with 4-, 8- and 16-wide vectors; each file
// is compiled for its instruction set). Lane by lane these are the floating-point operations of
// relax_element_scalar in the same order, on displacements from rest, through the rules written
// once over the lane type: weights times the proposals' offsets from the element summed over the
// neighbours -x, +x, -y, +y, -z, +z from zero (solver::ProposalSum), each link's box rebuilt from
// its tolerance (box_from_tau) and its interval (link_interval), the element's wall
// (solver::element_wall) lane by lane, max/min for the intersection, one IEEE division, the
// over-relaxed step kept below twice the correction (solver::relax_coordinate) and the clamp.
// No fused multiply-add (the build uses -ffp-contract=off, and the wide files do not enable FMA). Lanes
// whose boxes do not intersect, and the border elements of the lattice, go to the scalar rule.
// The last vector of a run is masked; its loads may run past the run into the next row, the
// stagger gap or the next plane, where another thread may be writing (the relaxation of an
// earlier half-sweep two planes ahead): those lanes are masked out and their values never used.
#include <algorithm>
#include <cmath>

#include "cpu/relax.hpp"
#include "cpu/simd.hpp"
#include "hpcm/state.hpp"

namespace hpcm::cpu::simd {

/// The vector rule over rows [ya, yb) of a run. AllRows: every row has all four y/z neighbours
/// (interior rows of an interior plane), so the neighbour loop is fully unrolled with
/// compile-time axes and sides and the accumulators stay in registers; border rows skip missing
/// neighbours by present[]. Several rows per call: the constants are set up once for all of
/// them, and the largest correction is reduced over the lanes once.
template <class V, bool AllRows>
float relax_span(const RelaxContext& c, const RelaxRun& r, int ya, int yb) {
  constexpr int N = sizeof(V) / sizeof(float);
  using M = Mask<V>;
  const Layout& L = *c.lay;
  const int nx = L.dims.x, ny = L.dims.y, nz = L.dims.z;
  // Columns of the changed flags are col_width (a power of two) run elements wide.
  int col_shift = 0;
  while ((1 << col_shift) < r.col_width) ++col_shift;
  // Everything the loop reads through the contexts, in locals: the byte stores of the marks may
  // alias any memory, and would otherwise make the compiler reload these on every vector.
  std::uint8_t* const col_changed = r.col_changed;
  const int col_base = r.col_base;
  float* const px = c.p[0];
  float* const py = c.p[1];
  float* const pz = c.p[2];
  const float* const weight = c.weight;
  const float* const link_tau[3] = {c.link_tau[0], c.link_tau[1], c.link_tau[2]};
  const std::uint8_t* const flags = c.flags;
  float max_corr = 0.0f;
  V max_sq_v = splat<V>(0.0f);  // largest squared correction applied by the vector lanes
  const V minus_inf = splat<V>(-solver::kInf), plus_inf = splat<V>(solver::kInf);
  const V zero = splat<V>(0.0f);
  const V omega = splat<V>(c.omega), threshold_sq = splat<V>(c.threshold_sq);
  const V slack_sq = splat<V>(c.slack_sq);
  // The element's wall (solver::element_wall): wall - X0, lane by lane on x, per row on y and z.
  const V wall_lo_x = splat<V>(c.wall.lo[0]), wall_hi_x = splat<V>(c.wall.hi[0]);
  const V wall_lo_z = splat<V>(solver::wall_lo_of(c.wall, 2, r.z)), wall_hi_z = splat<V>(solver::wall_hi_of(c.wall, 2, r.z));
  V lane_index;
  for (int l = 0; l < N; ++l) lane_index[l] = static_cast<float>(l);
  const V x_first = splat<V>(0.0f), x_last = splat<V>(static_cast<float>(nx - 1));

  for (int y = ya; y < yb; ++y) {
    const int h = (r.colour ^ y ^ r.z) & 1;  // the half whose elements have this colour
    const V wall_lo_y = splat<V>(solver::wall_lo_of(c.wall, 1, y)), wall_hi_y = splat<V>(solver::wall_hi_of(c.wall, 1, y));
    [[maybe_unused]] const bool present[6] = {true, true, y > 0, y + 1 < ny, r.z > 0, r.z + 1 < nz};
    auto scalar = [&](int j) {
      const float corr = relax_element_scalar(c, 2 * j + h, y, r.z);
      if (corr > 0.0f) {
        col_changed[(j - col_base) >> col_shift] = 1;
        max_corr = std::max(max_corr, corr);
      }
    };
    // x = 2j + h in [x0, x1): j in [x0 / 2, (x1 - h + 1) / 2)
    const int i0 = r.x0 / 2, i1 = (r.x1 - h + 1) / 2;
    const Index own0 = L.row_start(h, y, r.z);
    const Index oth0 = L.row_start(1 - h, y, r.z);
    const Index sy = L.width[h], sz = L.plane[h];
    // -x neighbour of element j: other half, index j - 1 (h = 0) or j (h = 1); +x: j or j + 1.
    const Index left = oth0 - (h == 0 ? 1 : 0), right = oth0 + (h == 0 ? 0 : 1);

    for (int j = i0; j < i1; j += N) {
      const Index k = own0 + j;
      // What this thread's first pass over the plane reads first: the +z neighbours' positions
      // and weights (the plane ahead of the wavefront) and the element's own link tolerances and
      // flags. Measured best about 8 lines ahead (BENCHMARKS.md).
      if (r.prefetch && prefetch_due<N>(j)) {
        constexpr int kAhead = 8 * kPrefetchLine;
        if (AllRows || present[5]) {
          const float* const ahead_plane[] = {px, py, pz, weight};
          for (const float* a : ahead_plane) prefetch(a + k + sz + kAhead);
        }
        for (const float* a : link_tau) prefetch(a + k + kAhead);
        prefetch(link_tau[0] + left + j + kAhead);
        prefetch(flags + k + kAhead);
      }
      const V cur0 = load<V>(px + k), cur1 = load<V>(py + k), cur2 = load<V>(pz + k);
      solver::ProposalSum<V> sum;
      // Lanes whose element has no -x (x = 0) or no +x (x = nx - 1) neighbour.
      const V x = splat<V>(static_cast<float>(h)) + splat<V>(2.0f) * (lane_index + splat<V>(static_cast<float>(j)));
      V lo0 = wall_lo_x - x, lo1 = wall_lo_y, lo2 = wall_lo_z;
      V hi0 = wall_hi_x - x, hi1 = wall_hi_y, hi2 = wall_hi_z;
      const M no_left = x == x_first, no_right = x == x_last;
      // Neighbour q in the rule's order -x, +x, -y, +y, -z, +z: axis q / 2, the element on the
      // neighbour's + side for even q. Same operations, same order as the scalar rule.
      auto neighbour = [&]<int q>(Index nk, Index owner) {
        constexpr int a = q / 2;
        constexpr bool plus_side = q % 2 == 0;
        V w = load<V>(weight + nk);
        [[maybe_unused]] M missing{};
        if constexpr (q == 0) missing = no_left;
        if constexpr (q == 1) missing = no_right;
        if constexpr (q < 2) w = missing ? zero : w;
        const V p0 = load<V>(px + nk), p1 = load<V>(py + nk), p2 = load<V>(pz + nk);
        // offsets from the element
        sum.add(w, sub_exact(p0, cur0), sub_exact(p1, cur1), sub_exact(p2, cur2));
        const LinkBox<V> box = box_from_tau(load<V>(link_tau[a] + owner));
        auto bound = [&](V& lo, V& hi, V pn, bool axial) {
          V l, u;
          link_interval(pn, box, axial, plus_side ? 1 : -1, l, u);
          if constexpr (q < 2) {
            l = missing ? minus_inf : l;
            u = missing ? plus_inf : u;
          }
          lo = vmax(lo, l);
          hi = vmin(hi, u);
        };
        bound(lo0, hi0, p0, a == 0);
        bound(lo1, hi1, p1, a == 1);
        bound(lo2, hi2, p2, a == 2);
      };
      neighbour.template operator()<0>(left + j, left + j);
      neighbour.template operator()<1>(right + j, k);
      if (AllRows || present[2]) neighbour.template operator()<2>(k - sy, k - sy);
      if (AllRows || present[3]) neighbour.template operator()<3>(k + sy, k);
      if (AllRows || present[4]) neighbour.template operator()<4>(k - sz, k - sz);
      if (AllRows || present[5]) neighbour.template operator()<5>(k + sz, k);

      const V t0 = sum.target(0, cur0, omega), t1 = sum.target(1, cur1, omega), t2 = sum.target(2, cur2, omega);
      // clampf, valid where lo <= hi
      const V out0 = vmax(lo0, vmin(hi0, t0)), out1 = vmax(lo1, vmin(hi1, t1)), out2 = vmax(lo2, vmin(hi2, t2));
      const V d0 = out0 - cur0, d1 = out1 - cur1, d2 = out2 - cur2;
      const V corr_sq = d0 * d0 + d1 * d1 + d2 * d2;
      const V disp_sq = cur0 * cur0 + cur1 * cur1 + cur2 * cur2;
      const M in_run = lane_index < splat<V>(static_cast<float>(i1 - j));
      const M boxes_meet = ~(lo0 > hi0) & ~(lo1 > hi1) & ~(lo2 > hi2);
      const M free = ((load_bytes<V>(flags + k) & static_cast<int>(kFixed)) == 0) & in_run;
      const M apply = boxes_meet & free & solver::relax_step_applies(corr_sq, threshold_sq, disp_sq, slack_sq);
      const unsigned applied = lane_bits<V>(apply), conflict = lane_bits<V>(free & ~boxes_meet);
      // No branch on `applied`: on a CT a tenth of the vectors apply nothing, scattered.
      if (j + N <= i1) {  // a full vector: every lane is this run's
        store<V>(px + k, apply ? out0 : cur0);
        store<V>(py + k, apply ? out1 : cur1);
        store<V>(pz + k, apply ? out2 : cur2);
        mark_columns(applied, j - col_base, col_shift, N, col_changed, true);
      } else {  // the masked tail: lanes past the run may belong to another thread's run
        store_lanes<V>(px + k, out0, applied);
        store_lanes<V>(py + k, out1, applied);
        store_lanes<V>(pz + k, out2, applied);
        mark_columns(applied, j - col_base, col_shift, N, col_changed);
      }
      max_sq_v = vmax(max_sq_v, apply ? corr_sq : zero);
      if (conflict)
        for (int l = 0; l < N; ++l)
          if (conflict >> l & 1u) scalar(j + l);
    }
  }
  // sqrtf is monotone, so the root of the largest square is the largest root.
  float max_sq = 0.0f;
  for (int l = 0; l < N; ++l) max_sq = std::max(max_sq, max_sq_v[l]);
  max_corr = std::max(max_corr, std::sqrt(max_sq));
  return max_corr;
}

/// The rule over one colour run (RelaxRun): interior rows of interior planes through the
/// unrolled kernel, in one call; the lattice's border rows through the general one.
template <class V>
float relax_run(const RelaxContext& c, const RelaxRun& r) {
  const int ny = c.lay->dims.y, nz = c.lay->dims.z;
  if (r.z == 0 || r.z + 1 == nz) return relax_span<V, false>(c, r, r.y0, r.y1);
  const int ya = std::max(r.y0, 1), yb = std::min(r.y1, ny - 1);
  float m = 0.0f;
  if (r.y0 < ya) m = std::max(m, relax_span<V, false>(c, r, r.y0, ya));
  if (ya < yb) m = std::max(m, relax_span<V, true>(c, r, ya, yb));
  if (yb < r.y1) m = std::max(m, relax_span<V, false>(c, r, yb, r.y1));
  return m;
}

}  // namespace hpcm::cpu::simd
