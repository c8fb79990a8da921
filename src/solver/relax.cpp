#include <algorithm>
#include <cmath>

#include "solver/chainmail.hpp"

namespace hpcm::solver {

namespace {

// The relaxation rule of rules.hpp (relax_element) unrolled for the CPU with precomputed
// weights, bit for bit the same floats: same neighbour order, same operations. Returns false
// when some axis has an empty box intersection (or no neighbour), where the caller falls back
// to the general rule with its conflict handling.
inline bool relax_fast(const Model& m, const float* W, const Vec3* pos, int x, int y, int z, Index i, float omega,
                       Vec3& out) {
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  const Index sy = nx, sz = static_cast<Index>(nx) * ny;
  float sx = 0, sY = 0, sZ = 0, sw = 0;
  float lo[3] = {-kInf, -kInf, -kInf}, hi[3] = {kInf, kInf, kInf};
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
  if (x > 0) visit(i - 1, 0, +1, m.link[0][i - 1]);
  if (x + 1 < nx) visit(i + 1, 0, -1, m.link[0][i]);
  if (y > 0) visit(i - sy, 1, +1, m.link[1][i - sy]);
  if (y + 1 < ny) visit(i + sy, 1, -1, m.link[1][i]);
  if (z > 0) visit(i - sz, 2, +1, m.link[2][i - sz]);
  if (z + 1 < nz) visit(i + sz, 2, -1, m.link[2][i]);
  if (count == 0 || lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) return false;
  const Vec3 avg{sx / sw, sY / sw, sZ / sw};
  const Vec3 cur = pos[i];
  const Vec3 target = omega == 1.0f ? avg
                                    : Vec3{cur.x + omega * (avg.x - cur.x), cur.y + omega * (avg.y - cur.y),
                                           cur.z + omega * (avg.z - cur.z)};
  for (int b = 0; b < 3; ++b) out[b] = clampf(target[b], lo[b], hi[b]);
  return true;
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
        Int3 lo, hi;
        grid_.range(b, lo, hi);
        Neighbour nb[6];
        bool any = false;
        for (int z = lo.z; z < hi.z; ++z)
          for (int y = lo.y; y < hi.y; ++y) {
            int x0 = lo.x + ((lo.x + y + z + colour) & 1);
            for (int x = x0; x < hi.x; x += 2) {
              const Index i = m.index(x, y, z);
              if (flags[i] & kFixed) continue;
              Vec3 p;
              if (!relax_fast(m, weight_.data(), pos.data(), x, y, z, i, omega, p)) {
                // Conflicting boxes (or an isolated element): the general rule decides.
                const int c = gather(m, pos.data(), time.data(), x, y, z, i, nb);
                if (c == 0) continue;
                p = relax_element(nb, c, pos[i], omega);
              }
              const Vec3 d = p - pos[i];
              const float corr = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
              if (!(corr >= threshold) || corr == 0.0f) continue;  // small corrections are skipped
              pos[i] = p;
              any = true;
              max_corr = std::max(max_corr, corr);
            }
          }
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

}  // namespace hpcm::solver
