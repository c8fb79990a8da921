#include <algorithm>
#include <cmath>
#include <limits>

#include "cpu/chainmail_cpu.hpp"
#include "solver/schedule.hpp"

namespace hpcm::cpu {

using namespace solver;

void ChainMailCpu::init(const Model& m, int brick_size) {
  grid_.init(m.dims, brick_size);
  touched_.assign(static_cast<std::size_t>(grid_.count), 0);
  hot_.assign(static_cast<std::size_t>(grid_.count), 0);
  changed_.assign(static_cast<std::size_t>(grid_.count), 0);
  final_.assign(static_cast<std::size_t>(m.size()), 0);
  weight_.resize(static_cast<std::size_t>(m.size()));
  for (Index i = 0; i < m.size(); ++i) weight_[i] = 1.0f / (m.tau[i] + 1e-4f);  // as in relax_element
  reached_.clear();
  buckets_.clear();
  delta_ = bucket_width(m);
}

int ChainMailCpu::gather(const Model& m, const Vec3* pos, const float* time, int x, int y, int z, Index i, Neighbour* nb) {
  int c = 0;
  for_each_face_neighbour(m, x, y, z, i, [&](Index n, int axis, int side, const LinkLimits& L) {
    nb[c++] = Neighbour{n, axis, side, L, time[n], m.tau[n], pos[n]};
  });
  return c;
}


PropagateStats ChainMailCpu::propagate(const Model& m, std::vector<Vec3>& pos, const std::vector<Vec3>& pre,
                                       std::vector<float>& time, const std::vector<std::uint8_t>& flags,
                                       const std::vector<Index>& fixed, int max_sweeps) {
  PropagateStats st;
  // Forget the previous wave.
  for (Index i : reached_) {
    time[i] = kInf;
    final_[i] = 0;
  }
  reached_.clear();
  for (auto& b : buckets_) b.clear();
  const double delta = delta_;
  auto bucket = [&](float t) { return static_cast<std::size_t>(bucket_of(t, delta)); };
  auto push_neighbours = [&](Index i, float t) {
    const Int3 c = m.coords(i);
    for_each_face_neighbour(m, c.x, c.y, c.z, i, [&](Index n, int, int, const LinkLimits& L) {
      if (final_[n] || (flags[n] & kFixed)) return;
      const std::size_t b = bucket(t + L.w);
      if (b >= buckets_.size()) buckets_.resize(b + 1);
      buckets_[b].push_back(n);
    });
  };
  for (Index f : fixed) {
    time[f] = 0.0f;
    final_[f] = 1;
    reached_.push_back(f);
    touched_[grid_.brick_of_index(f)] = 1;
    hot_[grid_.brick_of_index(f)] = 1;
  }
  for (Index f : fixed) push_neighbours(f, 0.0f);

  std::vector<Index> list;
  int iterations = 0;
  for (std::size_t k = 0; k < buckets_.size(); ++k) {
    if (buckets_[k].empty()) continue;
    list.swap(buckets_[k]);
    buckets_[k].clear();
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    list.erase(std::remove_if(list.begin(), list.end(), [&](Index e) { return final_[e] != 0; }), list.end());
    if (list.empty()) continue;
    const std::size_t n = list.size();
    if (scratch_t_.size() < n) {
      scratch_t_.resize(n);
      scratch_p_.resize(n);
    }
    // Jacobi inside the bucket: tentative times live in time[]/pos[] of the listed elements.
    // Dependencies inside a bucket go strictly down in candidate time, which is fixed by
    // earlier buckets, so this settles in at most (chain length + 1) passes.
    for (int pass = 0;; ++pass) {
      bool any = false;
#pragma omp parallel for schedule(static) reduction(|| : any) if (n > 2048)
      for (std::size_t j = 0; j < n; ++j) {
        const Index e = list[j];
        const Int3 c = m.coords(e);
        Neighbour nb[6];
        const int cnt = gather(m, pos.data(), time.data(), c.x, c.y, c.z, e, nb);
        propagate_in_bucket(e, pre[e], nb, cnt, k, delta, wall_, scratch_t_[j], scratch_p_[j]);
        if (!(scratch_t_[j] == time[e]) || !(scratch_p_[j] == pos[e])) any = true;
      }
      ++iterations;
      if (!any) break;
      if (pass >= max_sweeps) {
        st.converged = false;
        break;
      }
      for (std::size_t j = 0; j < n; ++j) {
        time[list[j]] = scratch_t_[j];
        pos[list[j]] = scratch_p_[j];
      }
    }
    for (Index e : list) {
      if (time[e] < kInf) {
        final_[e] = 1;
        reached_.push_back(e);
        ++st.reached;
        const Index b = grid_.brick_of_index(e);
        touched_[b] = 1;
        hot_[b] = 1;
      }
    }
    for (Index e : list)
      if (final_[e]) push_neighbours(e, time[e]);
    list.clear();
    // t + w >= (k+1)*delta mathematically, but float rounding can file a new candidate back
    // into this bucket: decide those too before moving on.
    if (!buckets_[k].empty()) --k;
  }
  st.sweeps = iterations;
  last_active_ = 0;
  for (std::uint8_t t : touched_) last_active_ += t;
  return st;
}

}  // namespace hpcm::cpu
