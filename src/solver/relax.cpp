#include <algorithm>
#include <cmath>

#include "solver/chainmail.hpp"

namespace hpcm::solver {

// Red-black Gauss-Seidel: the 6-connected lattice is bipartite, so all elements of one colour
// can move at once, each clamped into the boxes of its (unmoving) neighbours of the other
// colour. Every link is therefore within its box after each half-sweep, whatever the thread
// count, and the result is deterministic.
RelaxStats ChainMailCpu::relax(const Model& m, std::vector<Vec3>& pos, const std::vector<float>& time,
                               const std::vector<std::uint8_t>& flags, int sweeps, float threshold, float omega) {
  RelaxStats st;
  Index active_max = last_active_;
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
              const int c = gather(m, pos.data(), time.data(), x, y, z, i, nb);
              if (c == 0) continue;
              const Vec3 p = relax_element(nb, c, pos[i], omega);
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
