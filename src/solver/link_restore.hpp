#pragma once
// The host schedule of the link restoration (rule and reasoning: solver/restore.hpp): a
// sequential work list per axis, restricted to the elements around the links found violated.
// Used by the CPU backend, and by the CUDA backend on its host copy.
#include <cstdint>
#include <vector>

#include "hpcm/model.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"
#include "solver/restore.hpp"

namespace hpcm::solver {

class LinkRestorer {
 public:
  void init(const Model& m);
  /// Checks every link with an end in `bricks` (and the boundary box); when one is violated
  /// by more than solver::kRestoreTolerance, restores consistency around it. FIXED elements
  /// (flags & kFixed) never move. Bricks whose elements moved are flagged in `moved`.
  RestoreStats run(const Model& m, const BrickGrid& grid, const std::vector<Index>& bricks,
                   std::vector<Vec3>& pos, const std::vector<std::uint8_t>& flags, const Wall& wall,
                   std::vector<std::uint8_t>& moved);

 private:
  /// One pass over coordinate b of the copy `k` (0 or 1), seeded with `seeds`; appends the
  /// elements whose value changed to `changed` (each once per axis).
  void pass(const Model& m, const std::vector<Vec3>& pos, const std::vector<std::uint8_t>& flags, int b, int k,
            float wall_lo, float wall_hi, bool upper, const std::vector<Index>& seeds);
  /// The coordinate of element e in copy k, loaded from pos on first use in this axis.
  float& value(const std::vector<Vec3>& pos, int b, int k, Index e) {
    if (stamp_[e] != epoch_) {
      stamp_[e] = epoch_;
      val_[0][e] = val_[1][e] = pos[e][b];
      mark_[e] = 0;
    }
    return val_[k][e];
  }
  std::vector<Index> seeds_, changed_, queue_, pass_seeds_, moved_list_;
  std::vector<std::uint8_t> queued_, mark_, moved_flag_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t epoch_ = 0;
  std::vector<float> val_[2];  ///< coordinate b under the two pass orders
};

}  // namespace hpcm::solver
