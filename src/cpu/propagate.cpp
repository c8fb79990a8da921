#include "cpu/propagate.hpp"

#include <algorithm>

#include "hpcm/state.hpp"
#include "solver/neighbours.hpp"

namespace hpcm::cpu {

using namespace solver;

void Propagation::init(const Model& m, const Layout& lay, const BrickGrid& grid) {
  m_ = &m;
  grid_ = grid;
  final_.assign(static_cast<std::size_t>(lay.span), 0);  // storage order
  still_mark_.assign(static_cast<std::size_t>(lay.span), 0);
  reached_.clear();
  still_.clear();
  next_still_.clear();
  still_pending_ = false;
  buckets_.clear();
}

void Propagation::recycle(std::vector<Index>& pending) {
  if (pending.capacity() == 0) return;
  pending.clear();
  spare_.emplace_back();
  spare_.back().swap(pending);
}

int Propagation::gather(const Storage& st, Index e, Neighbour* nb) const {
  const Model& m = *m_;
  const Int3 c = m.coords(e);
  int count = 0;
  for_each_face_neighbour(m.dims.x, m.dims.y, m.dims.z, c.x, c.y, c.z, e,
                          [&](Index n, int axis, int side, Index lo, Index) {
                            const Index k = st.lay.at(n);
                            nb[count++] = Neighbour{n, axis, side, m.link(axis, lo), st.time[k],
                                                    m.tau[static_cast<std::size_t>(n)],
                                                    Vec3{st.p[0][k], st.p[1][k], st.p[2][k]}};
                          });
  return count;
}

void Propagation::set_still(const std::vector<Index>& still) {
  next_still_ = still;
  still_pending_ = true;
}

PropagateStats Propagation::run(Storage& st, const std::vector<Index>& tool, const Wall& wall, int max_sweeps,
                                std::vector<std::uint8_t>& touched, std::vector<std::uint8_t>& hot, WorkerPool& pool) {
  const Model& m = *m_;
  const Layout& L = st.lay;
  PropagateStats ps;
  auto forget = [&](Index i) {
    const Index k = L.at(i);
    st.time[k] = kInf;
    final_[k] = 0;
  };
  // Forget the previous wave (it never lists a still element: those stay final with time 0).
  for (Index i : reached_) forget(i);
  reached_.clear();
  if (still_pending_) {
    for (Index i : still_) {
      forget(i);
      still_mark_[L.at(i)] = 0;
    }
    still_.swap(next_still_);
    next_still_.clear();
    for (Index i : still_) {
      const Index k = L.at(i);
      st.time[k] = 0.0f;
      final_[k] = 1;
      still_mark_[k] = 1;
    }
    still_pending_ = false;
  }
  for (auto& entry : buckets_) recycle(entry.second);
  buckets_.clear();
  const double delta = delta_;
  // `processed`: the bucket being decided. A push below it (float rounding) is dropped: that
  // bucket is decided and is not visited again. A push into it is decided before moving on.
  auto push = [&](Index n, unsigned long long b) {
    auto [it, added] = buckets_.try_emplace(b);
    if (added && !spare_.empty()) {
      it->second.swap(spare_.back());
      spare_.pop_back();
    }
    it->second.push_back(n);
  };
  auto push_neighbours = [&](Index i, float t, unsigned long long processed) {
    const Int3 c = m.coords(i);
    for_each_face_neighbour(m, c.x, c.y, c.z, i, [&](Index n, int, int, const LinkLimits& lim) {
      const Index k = L.at(n);
      if (final_[k] || (st.flags[k] & kFixed)) return;
      const unsigned long long b = bucket_of(t + lim.w, delta);
      if (b < processed) return;
      push(n, b);
      // The rule also tries the candidate times of n's anchors (time 0, so c = w), which push
      // nothing themselves: those after i's key, with i now upstream, go to their own buckets.
      const Int3 cn = m.coords(n);
      for_each_face_neighbour(m, cn.x, cn.y, cn.z, n, [&](Index f, int, int, const LinkLimits& lf) {
        const std::uint8_t ff = st.flags[L.at(f)];
        if (!(ff & kFixed) || (ff & kGrabbed)) return;
        const float cf = lf.w;
        if (!(t < cf || (t == cf && i < n))) return;
        const unsigned long long bf = bucket_of(cf, delta);
        if (bf != b && bf >= processed) push(n, bf);
      });
    });
  };
  for (Index f : tool) {
    const Index k = L.at(f);
    if (still_mark_[k]) continue;  // also still: final with time 0 already
    st.time[k] = 0.0f;
    final_[k] = 1;
    reached_.push_back(f);
  }
  for (Index f : tool)
    if (st.flags[L.at(f)] & kGrabbed) {
      const Index b = grid_.brick_of_index(f);
      touched[b] = hot[b] = 1;
      push_neighbours(f, 0.0f, 0);
    }

  std::vector<Index> list;
  int iterations = 0;
  constexpr std::int64_t kChunk = 1024;  // elements per work item of a large bucket
  // Buckets in ascending order; a bucket that gets new candidates while it is decided (float
  // rounding, see below) is the smallest again and is decided again.
  while (!buckets_.empty()) {
    const auto first = buckets_.begin();
    const unsigned long long kb = first->first;
    list.swap(first->second);
    recycle(first->second);
    buckets_.erase(first);
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    list.erase(std::remove_if(list.begin(), list.end(), [&](Index e) { return final_[L.at(e)] != 0; }), list.end());
    if (list.empty()) continue;
    const std::int64_t n = static_cast<std::int64_t>(list.size());
    ps.largest_bucket = std::max(ps.largest_bucket, static_cast<Index>(n));
    if (static_cast<std::int64_t>(scratch_t_.size()) < n) {
      scratch_t_.resize(static_cast<std::size_t>(n));
      scratch_p_.resize(static_cast<std::size_t>(n));
    }
    // Jacobi inside the bucket: tentative times live in time[]/p[] of the listed elements.
    // Dependencies inside a bucket go strictly down in candidate time, which is fixed by
    // earlier buckets, so this settles in at most (chain length + 1) passes.
    const std::int64_t chunks = (n + kChunk - 1) / kChunk;
    chunk_any_.assign(static_cast<std::size_t>(chunks), 0);
    for (int pass = 0;; ++pass) {
      pool.run(
          chunks,
          [&](std::int64_t ch) {
            std::uint8_t any = 0;
            for (std::int64_t j = ch * kChunk; j < std::min(n, (ch + 1) * kChunk); ++j) {
              const Index e = list[static_cast<std::size_t>(j)];
              const Index k = L.at(e);
              Neighbour nb[6];
              const int cnt = gather(st, e, nb);
              float& t = scratch_t_[static_cast<std::size_t>(j)];
              Vec3& p = scratch_p_[static_cast<std::size_t>(j)];
              const Int3 c = m.coords(e);
              propagate_in_bucket(e, Vec3{st.q[0][k], st.q[1][k], st.q[2][k]}, nb, cnt, kb, delta,
                                  element_wall(wall, c.x, c.y, c.z), t, p);
              if (!(t == st.time[k]) || !(p == Vec3{st.p[0][k], st.p[1][k], st.p[2][k]})) any = 1;
            }
            chunk_any_[static_cast<std::size_t>(ch)] = any;
          },
          2);
      ++iterations;
      const bool any = std::any_of(chunk_any_.begin(), chunk_any_.end(), [](std::uint8_t a) { return a != 0; });
      if (!any) break;
      if (pass >= max_sweeps) {
        ps.converged = false;
        break;
      }
      for (std::int64_t j = 0; j < n; ++j) {
        const Index k = L.at(list[static_cast<std::size_t>(j)]);
        st.time[k] = scratch_t_[static_cast<std::size_t>(j)];
        const Vec3 p = scratch_p_[static_cast<std::size_t>(j)];
        st.p[0][k] = p.x;
        st.p[1][k] = p.y;
        st.p[2][k] = p.z;
      }
    }
    for (Index e : list) {
      const Index k = L.at(e);
      if (st.time[k] < kInf) {
        final_[k] = 1;
        reached_.push_back(e);
        ++ps.reached;
        const Index b = grid_.brick_of_index(e);
        touched[b] = hot[b] = 1;
      }
    }
    // t + w >= (k+1)*delta mathematically, but float rounding can file a new candidate back
    // into this bucket: it is then the smallest pending one and is decided again next.
    for (Index e : list)
      if (final_[L.at(e)]) push_neighbours(e, st.time[L.at(e)], kb);
    list.clear();
  }
  ps.sweeps = iterations;
  return ps;
}

}  // namespace hpcm::cpu
