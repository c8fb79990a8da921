#pragma once
// Gibson's classic sequential 3D ChainMail (S. Gibson, "3D ChainMail", I3D 1997), with the
// per-link limits of the heterogeneous model. The benchmark baseline: one pass, no
// timestamps. Moved elements wait in a FIFO queue; each popped mover checks its unmoved
// neighbours against its own link box and moves a violating neighbour minimally into it
// (per-axis clamp of the neighbour's current position), marks it moved and queues it (the
// mover "sponsors" the neighbour). An element moves at most once per wave; FIXED elements
// are the first movers. Unlike the timestamped rule (dijkstra.hpp) the result depends on
// the visiting order, and a neighbour that moved first is never corrected by a later
// sponsor, so heterogeneous lattices can end with violated links.
#include <cstdint>
#include <vector>

#include "hpcm/model.hpp"

namespace hpcm::reference {

class GibsonChainMail {
 public:
  explicit GibsonChainMail(const Model& m);
  /// One wave in place: `pos` holds the start positions on entry and the result on exit.
  /// `fixed` are the movers (placed at `targets`). Returns the number of non-FIXED elements moved.
  Index run(std::vector<Vec3>& pos, const std::vector<Index>& fixed, const std::vector<Vec3>& targets);
  /// Elements marked moved by the last run (FIXED included), for tests.
  bool moved(Index i) const { return moved_[static_cast<std::size_t>(i)] != 0; }

 private:
  const Model& m_;
  std::vector<std::uint8_t> moved_;
  std::vector<Index> queue_;  ///< FIFO (head index), also the list of marked elements
};

/// Convenience wrapper: one wave with a fresh solver; returns the positions.
std::vector<Vec3> gibson_propagate(const Model& m, const std::vector<Vec3>& p0, const std::vector<Index>& fixed,
                                   const std::vector<Vec3>& targets);

}  // namespace hpcm::reference
