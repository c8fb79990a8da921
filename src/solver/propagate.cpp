#include <algorithm>
#include <limits>

#include "solver/chainmail.hpp"

namespace hpcm::solver {

void ChainMailCpu::init(const Model& m, int brick_size) {
  grid_.init(m.dims, brick_size);
  touched_.assign(static_cast<std::size_t>(grid_.count), 0);
  hot_.assign(static_cast<std::size_t>(grid_.count), 0);
  changed_.assign(static_cast<std::size_t>(grid_.count), 0);
  wave_.assign(static_cast<std::size_t>(grid_.count), 0);
}

int ChainMailCpu::gather(const Model& m, const Vec3* pos, const float* time, int x, int y, int z, Index i, Neighbour* nb) {
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  const Index sy = nx, sz = static_cast<Index>(nx) * ny;
  int c = 0;
  auto add = [&](Index n, int axis, int side, const LinkLimits& L) {
    nb[c++] = Neighbour{n, axis, side, L, time[n], m.tau[n], pos[n]};
  };
  // Fixed neighbour order (-x, +x, -y, +y, -z, +z): sums are reproducible.
  if (x > 0) add(i - 1, 0, +1, m.link[0][i - 1]);
  if (x + 1 < nx) add(i + 1, 0, -1, m.link[0][i]);
  if (y > 0) add(i - sy, 1, +1, m.link[1][i - sy]);
  if (y + 1 < ny) add(i + sy, 1, -1, m.link[1][i]);
  if (z > 0) add(i - sz, 2, +1, m.link[2][i - sz]);
  if (z + 1 < nz) add(i + sz, 2, -1, m.link[2][i]);
  return c;
}

PropagateStats ChainMailCpu::propagate(const Model& m, std::vector<Vec3>& pos, const std::vector<Vec3>& pre,
                                       std::vector<float>& time, const std::vector<std::uint8_t>& flags,
                                       const std::vector<Index>& fixed, int max_sweeps) {
  PropagateStats st;
  const Index B3 = static_cast<Index>(grid_.size) * grid_.size * grid_.size;
  // Forget the previous wave: times back to +inf where it went.
  BrickGrid::to_list(wave_, list_);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t k = 0; k < list_.size(); ++k) {
    Int3 lo, hi;
    grid_.range(list_[k], lo, hi);
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) time[m.index(x, y, z)] = kInf;
  }
  std::fill(wave_.begin(), wave_.end(), 0);
  std::fill(changed_.begin(), changed_.end(), 0);
  for (Index f : fixed) {
    time[f] = 0.0f;
    const Index b = grid_.brick_of_index(f);
    changed_[b] = 1;
    wave_[b] = 1;
    touched_[b] = 1;
  }
  Index active_total = 0;
  int sweep = 0;
  for (;;) {
    grid_.dilate_to_list(changed_, list_);
    if (list_.empty()) break;
    if (sweep >= max_sweeps) {
      st.converged = false;
      break;
    }
    ++sweep;
    active_total = std::max<Index>(active_total, static_cast<Index>(list_.size()));
    const std::size_t nlist = list_.size();
    if (scratch_t_.size() < nlist * B3) {
      scratch_t_.resize(nlist * B3);
      scratch_p_.resize(nlist * B3);
    }
    std::fill(changed_.begin(), changed_.end(), 0);
    // Jacobi: compute every element of the active bricks from the current buffers ...
#pragma omp parallel for schedule(dynamic, 1)
    for (std::size_t k = 0; k < nlist; ++k) {
      Int3 lo, hi;
      grid_.range(list_[k], lo, hi);
      float* st_t = scratch_t_.data() + k * B3;
      Vec3* st_p = scratch_p_.data() + k * B3;
      Neighbour nb[6];
      bool any = false;
      Index s = 0;
      for (int z = lo.z; z < hi.z; ++z)
        for (int y = lo.y; y < hi.y; ++y)
          for (int x = lo.x; x < hi.x; ++x, ++s) {
            const Index i = m.index(x, y, z);
            if (flags[i] & kFixed) {
              st_t[s] = time[i];
              st_p[s] = pos[i];
              continue;
            }
            const int c = gather(m, pos.data(), time.data(), x, y, z, i, nb);
            propagate_element(i, pre[i], nb, c, st_t[s], st_p[s]);
            if (!(st_t[s] == time[i]) || !(st_p[s] == pos[i])) any = true;
          }
      changed_[list_[k]] = any;
    }
    // ... then publish the changed bricks.
#pragma omp parallel for schedule(dynamic, 1)
    for (std::size_t k = 0; k < nlist; ++k) {
      const Index b = list_[k];
      if (!changed_[b]) continue;
      wave_[b] = 1;
      touched_[b] = 1;
      hot_[b] = 1;
      Int3 lo, hi;
      grid_.range(b, lo, hi);
      const float* st_t = scratch_t_.data() + k * B3;
      const Vec3* st_p = scratch_p_.data() + k * B3;
      Index s = 0;
      for (int z = lo.z; z < hi.z; ++z)
        for (int y = lo.y; y < hi.y; ++y)
          for (int x = lo.x; x < hi.x; ++x, ++s) {
            const Index i = m.index(x, y, z);
            time[i] = st_t[s];
            pos[i] = st_p[s];
          }
    }
  }
  st.sweeps = sweep;
  // Count the elements the wave reached.
  BrickGrid::to_list(wave_, list_);
  Index reached = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : reached)
  for (std::size_t k = 0; k < list_.size(); ++k) {
    Int3 lo, hi;
    grid_.range(list_[k], lo, hi);
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
          const Index i = m.index(x, y, z);
          if (!(flags[i] & kFixed) && time[i] < kInf) ++reached;
        }
  }
  st.reached = reached;
  last_active_ = active_total;
  return st;
}

}  // namespace hpcm::solver
