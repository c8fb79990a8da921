#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "cpu/chainmail_cpu.hpp"

namespace hpcm::cpu {

using namespace solver;

namespace {

// The relaxation rule of rules.hpp (relax_element) unrolled for the CPU with precomputed
// weights, bit for bit the same floats: same neighbour order, same operations. Returns false
// when some axis has an empty box intersection (or no neighbour), where the caller falls back
// to the general rule with its conflict handling.
inline bool relax_fast(const Model& m, const float* W, const Vec3* pos, int x, int y, int z, Index i, float omega,
                       const Wall& wall, Vec3& out) {
  float sx = 0, sY = 0, sZ = 0, sw = 0;
  float lo[3] = {wall.lo[0], wall.lo[1], wall.lo[2]}, hi[3] = {wall.hi[0], wall.hi[1], wall.hi[2]};
  int count = 0;
  auto visit = [&](Index n, int axis, int side, const LinkLimits& L) {
    ++count;
    const float w = W[n];
    Vec3 prop = pos[n];
    const Vec3 pn = prop;
    prop[axis] += static_cast<float>(side);
    sx += w * prop.x;
    sY += w * prop.y;
    sZ += w * prop.z;
    sw += w;
    for (int b = 0; b < 3; ++b) {
      float l, h;
      link_interval(pn, L, axis, side, b, l, h);
      lo[b] = lo[b] > l ? lo[b] : l;
      hi[b] = hi[b] < h ? hi[b] : h;
    }
  };
  for_each_face_neighbour(m, x, y, z, i, visit);
  if (count == 0 || lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) return false;
  const Vec3 avg{sx / sw, sY / sw, sZ / sw};
  const Vec3 cur = pos[i];
  const Vec3 target = omega == 1.0f ? avg
                                    : Vec3{cur.x + omega * (avg.x - cur.x), cur.y + omega * (avg.y - cur.y),
                                           cur.z + omega * (avg.z - cur.z)};
  for (int b = 0; b < 3; ++b) out[b] = clampf(target[b], lo[b], hi[b]);
  return true;
}

#if defined(__SSE2__)
// relax_fast for an element with all six neighbours (0 < x < nx-1, same for y and z): no
// bounds tests, and the three components in one SSE register, bit for bit the same floats:
// each lane does the scalar operations in the same order, and
//  * prop = pn + (side on the axis lane, +0 on the others): pn + 0 differs from pn only for
//    pn = -0 (gives +0), and the sum sx = 0 + w*prop_1 + ... can never be -0 (a sum of
//    round-to-nearest is -0 only when both terms are -0 and the start is +0), so the sums
//    are unchanged;
//  * c - m is computed as c + (-m), which IEEE 754 defines to be the same operation;
//  * maxps(lo, l) is lo > l ? lo : l and minps(hi, h) is hi < h ? hi : h, exactly the scalar
//    ternaries; with !(lo > hi) (checked before), clampf(x, lo, hi) equals maxps(lo, minps(hi, x));
//  * lane 3 carries junk (the next element's x) and is never used.
// Loads of 16 bytes at pos[n] read pos[n + 1].x, which exists for every neighbour n of an
// interior element (n <= i + sz and i <= size - 2). That element may be one of the colour being
// written by another thread at the same moment: its value lands in lane 3 and is never used.
template <int A, int S>
inline void visit_sse(const Vec3* pos, const float* W, const LinkLimits* link, Index n, Index li, __m128& sum,
                      float& sw, __m128& lo, __m128& hi) {
  const __m128 pn = _mm_loadu_ps(&pos[n].x);
  const float w = W[n];
  const __m128 side = _mm_setr_ps(A == 0 ? float(S) : 0.0f, A == 1 ? float(S) : 0.0f, A == 2 ? float(S) : 0.0f, 0.0f);
  const __m128 prop = _mm_add_ps(pn, side);
  sum = _mm_add_ps(sum, _mm_mul_ps(_mm_set1_ps(w), prop));
  sw += w;
  const __m128 L = _mm_loadu_ps(&link[li].min_d);  // min_d, max_d, shear, w
  // Offsets added to pn: S > 0: lo = c + min_d, hi = c + max_d on the axis;
  // S < 0: lo = c + (-max_d), hi = c + (-min_d); off the axis lo = c + (-shear), hi = c + shear.
  constexpr int lo_src = S > 0 ? 0 : 1, hi_src = S > 0 ? 1 : 0;
  constexpr int lo_sel = ((A == 0 ? lo_src : 2) << 0) | ((A == 1 ? lo_src : 2) << 2) | ((A == 2 ? lo_src : 2) << 4) | (2 << 6);
  constexpr int hi_sel = ((A == 0 ? hi_src : 2) << 0) | ((A == 1 ? hi_src : 2) << 2) | ((A == 2 ? hi_src : 2) << 4) | (2 << 6);
  const float ng = -0.0f;
  const __m128 lo_neg = _mm_setr_ps(A == 0 && S > 0 ? 0.0f : ng, A == 1 && S > 0 ? 0.0f : ng, A == 2 && S > 0 ? 0.0f : ng, 0.0f);
  const __m128 hi_neg = _mm_setr_ps(A == 0 && S < 0 ? ng : 0.0f, A == 1 && S < 0 ? ng : 0.0f, A == 2 && S < 0 ? ng : 0.0f, 0.0f);
  const __m128 lo_off = _mm_xor_ps(_mm_shuffle_ps(L, L, lo_sel), lo_neg);
  const __m128 hi_off = S > 0 ? _mm_shuffle_ps(L, L, hi_sel) : _mm_xor_ps(_mm_shuffle_ps(L, L, hi_sel), hi_neg);
  const __m128 l = _mm_add_ps(pn, lo_off);
  const __m128 h = _mm_add_ps(pn, hi_off);
  lo = _mm_max_ps(lo, l);
  hi = _mm_min_ps(hi, h);
}

// Returns false on an empty intersection (caller falls back to the general rule).
inline bool relax_interior_sse(const LinkLimits* L0, const LinkLimits* L1, const LinkLimits* L2, const float* W,
                               const Vec3* pos, Index i, Index sy, Index sz, float omega, const Wall& wall, Vec3& out) {
  __m128 sum = _mm_setzero_ps();
  __m128 lo = _mm_setr_ps(wall.lo[0], wall.lo[1], wall.lo[2], 0.0f);
  __m128 hi = _mm_setr_ps(wall.hi[0], wall.hi[1], wall.hi[2], 0.0f);
  float sw = 0;
  visit_sse<0, +1>(pos, W, L0, i - 1, i - 1, sum, sw, lo, hi);
  visit_sse<0, -1>(pos, W, L0, i + 1, i, sum, sw, lo, hi);
  visit_sse<1, +1>(pos, W, L1, i - sy, i - sy, sum, sw, lo, hi);
  visit_sse<1, -1>(pos, W, L1, i + sy, i, sum, sw, lo, hi);
  visit_sse<2, +1>(pos, W, L2, i - sz, i - sz, sum, sw, lo, hi);
  visit_sse<2, -1>(pos, W, L2, i + sz, i, sum, sw, lo, hi);
  if (_mm_movemask_ps(_mm_cmpgt_ps(lo, hi)) & 7) return false;
  const __m128 avg = _mm_div_ps(sum, _mm_set1_ps(sw));
  const __m128 cur = _mm_loadu_ps(&pos[i].x);
  const __m128 target = omega == 1.0f ? avg : _mm_add_ps(cur, _mm_mul_ps(_mm_set1_ps(omega), _mm_sub_ps(avg, cur)));
  const __m128 p = _mm_max_ps(lo, _mm_min_ps(hi, target));
  float r[4];
  _mm_storeu_ps(r, p);
  out = Vec3{r[0], r[1], r[2]};
  return true;
}
#endif

// What the per-brick worker reads and writes.
struct RelaxCtx {
  const Model* m;
  const BrickGrid* grid;
  const LinkLimits *L0, *L1, *L2;
  const float* W;
  const float* time;
  const std::uint8_t* F;
  Vec3* P;
  float threshold, omega;
  Wall wall;
};

// One colour of one brick: the elements (x + y + z) % 2 == colour, visited row by row.
// Returns the largest correction applied (0 if none); sets `any` when something moved.
inline float relax_brick(const RelaxCtx& c, Index b, int colour, bool& any) {
  const Model& m = *c.m;
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  [[maybe_unused]] const Index sy = nx, sz = static_cast<Index>(nx) * ny;  // SSE path only
  Int3 lo, hi;
  c.grid->range(b, lo, hi);
  Neighbour nb[6];
  float max_corr = 0.0f;
  for (int z = lo.z; z < hi.z; ++z)
    for (int y = lo.y; y < hi.y; ++y) {
      [[maybe_unused]] const bool yz_interior = y > 0 && y + 1 < ny && z > 0 && z + 1 < nz;
      int x = lo.x + ((lo.x + y + z + colour) & 1);
      Index i = m.index(x, y, z);
      for (; x < hi.x; x += 2, i += 2) {
        if (c.F[i] & kFixed) continue;
        Vec3 p;
#if defined(__SSE2__)
        const bool interior = yz_interior && x > 0 && x + 1 < nx;
        const bool ok = interior ? relax_interior_sse(c.L0, c.L1, c.L2, c.W, c.P, i, sy, sz, c.omega, c.wall, p)
                                 : relax_fast(m, c.W, c.P, x, y, z, i, c.omega, c.wall, p);
#else
        const bool ok = relax_fast(m, c.W, c.P, x, y, z, i, c.omega, c.wall, p);
#endif
        if (!ok) {
          // Conflicting boxes (or an isolated element): the general rule decides.
          const int cnt = ChainMailCpu::gather(m, c.P, c.time, x, y, z, i, nb);
          if (cnt == 0) continue;
          p = relax_element(nb, cnt, c.P[i], c.omega, c.wall);
        }
        const Vec3 d = p - c.P[i];
        const float corr = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        if (!(corr >= c.threshold) || corr == 0.0f) continue;  // small corrections are skipped
        c.P[i] = p;
        any = true;
        max_corr = std::max(max_corr, corr);
      }
    }
  return max_corr;
}

}  // namespace

// Red-black Gauss-Seidel: the 6-connected lattice is bipartite, so all elements of one colour
// can move at once, each clamped into the boxes of its (unmoving) neighbours of the other
// colour. Every link is therefore within its box after each half-sweep, whatever the thread
// count, and the result is deterministic.
RelaxStats ChainMailCpu::relax(const Model& m, std::vector<Vec3>& pos, const std::vector<float>& time,
                               const std::vector<std::uint8_t>& flags, int sweeps, float threshold, float omega) {
  RelaxStats st;
  Index active_max = 0;  // this call only; the backend combines it with propagation's
  std::vector<std::uint8_t>& work = hot_;
  const RelaxCtx ctx{&m,         &grid_,      m.link[0].data(), m.link[1].data(), m.link[2].data(),
                     weight_.data(), time.data(), flags.data(),     pos.data(),       threshold,
                     omega,      wall_};
  for (int s = 0; s < sweeps; ++s) {
    grid_.dilate_to_list(work, list_);
    if (list_.empty()) break;
    active_max = std::max<Index>(active_max, static_cast<Index>(list_.size()));
    std::fill(changed_.begin(), changed_.end(), 0);
    float max_corr = 0.0f;
    for (int colour = 0; colour < 2; ++colour) {
#pragma omp parallel for schedule(dynamic, 1) reduction(max : max_corr)
      for (std::size_t k = 0; k < list_.size(); ++k) {
        const Index b = list_[k];
        bool any = false;
        const float mc = relax_brick(ctx, b, colour, any);
        max_corr = std::max(max_corr, mc);
        if (any) changed_[b] = 1;
      }
    }
    ++st.sweeps;
    st.max_correction = max_corr;
    for (std::size_t k = 0; k < list_.size(); ++k)
      if (changed_[list_[k]]) touched_[list_[k]] = 1;
    // The next sweep works where this one changed something.
    std::swap(hot_, changed_);
    if (max_corr < threshold || max_corr == 0.0f) break;  // early exit
  }
  last_active_ = active_max;
  return st;
}

}  // namespace hpcm::cpu
