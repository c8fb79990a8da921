// Gibson's classic sequential 3D ChainMail (see gibson.hpp).
#include "solver/reference/gibson.hpp"

#include <algorithm>

#include "solver/reference/dijkstra.hpp"

namespace hpcm::reference {

GibsonChainMail::GibsonChainMail(const Model& m) : m_(m), moved_(static_cast<std::size_t>(m.size()), 0) {}

Index GibsonChainMail::run(std::vector<Vec3>& pos, const std::vector<Index>& fixed, const std::vector<Vec3>& targets) {
  if (pos.size() != static_cast<std::size_t>(m_.size()))
    throw Error("gibson: position array has " + std::to_string(pos.size()) + " entries for " +
                std::to_string(m_.size()) + " elements");
  if (fixed.size() != targets.size()) throw Error("gibson: fixed and targets differ in size");
  for (Index i : queue_) moved_[static_cast<std::size_t>(i)] = 0;
  queue_.clear();
  for (std::size_t k = 0; k < fixed.size(); ++k) {
    const Index i = fixed[k];
    if (i < 0 || i >= m_.size()) throw Error("gibson: fixed element " + std::to_string(i) + " out of range");
    pos[static_cast<std::size_t>(i)] = targets[k];
    if (!moved_[static_cast<std::size_t>(i)]) {
      moved_[static_cast<std::size_t>(i)] = 1;
      queue_.push_back(i);
    }
  }
  const std::size_t sources = queue_.size();
  Neighbour nb[6];
  for (std::size_t head = 0; head < queue_.size(); ++head) {
    const Index mover = queue_[head];
    const Vec3 pm = pos[static_cast<std::size_t>(mover)];
    const int cnt = neighbours(m_, mover, nb);
    for (int k = 0; k < cnt; ++k) {
      const std::size_t n = static_cast<std::size_t>(nb[k].n);
      if (moved_[n]) continue;
      // nb[k].e_plus says whether the mover is on the + side of n; n is on the other side.
      const Vec3 p = pos[n];
      Vec3 q;
      for (int b = 0; b < 3; ++b) {
        const Interval iv = link_interval(nb[k].L, nb[k].axis, !nb[k].e_plus, pm, b);
        q[b] = std::min(std::max(p[b], iv.lo), iv.hi);
      }
      if (q == p) continue;
      pos[n] = q;
      moved_[n] = 1;
      queue_.push_back(nb[k].n);
    }
  }
  return static_cast<Index>(queue_.size() - sources);
}

std::vector<Vec3> gibson_propagate(const Model& m, const std::vector<Vec3>& p0, const std::vector<Index>& fixed,
                                   const std::vector<Vec3>& targets) {
  GibsonChainMail g(m);
  std::vector<Vec3> pos = p0;
  g.run(pos, fixed, targets);
  return pos;
}

}  // namespace hpcm::reference
