#pragma once
// The host schedule of the link restoration (rule and reasoning: solver/restore.hpp): a
// sequential work list per axis, restricted to the elements around the links found violated.
// Used by the CPU backend on its storage and by the CUDA backend on a host copy; positions are
// reached through RestoreAccess, so the element storage order is the backend's business.
#include <cstdint>
#include <functional>
#include <vector>

#include "hpcm/model.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"
#include "solver/restore.hpp"

namespace hpcm::solver {

/// Displacements from rest and FIXED flags of a backend, by linear element index.
struct RestoreAccess {
  virtual ~RestoreAccess() = default;
  virtual Vec3 displacement(Index i) const = 0;
  virtual void set_coordinate(Index i, int axis, float value) = 0;
  virtual bool fixed(Index i) const = 0;
};

/// Finds the links with an end in `bricks` (and the elements there outside the wall) violated
/// by more than kRestoreTolerance; appends both ends (each once, ascending) to `seeds` and
/// counts them in `st`. Generic over RestoreAccess (a backend may have a faster check).
void find_violations(const Model& m, const BrickGrid& grid, const std::vector<Index>& bricks, const RestoreAccess& pos,
                     const Wall& wall, std::vector<Index>& seeds, RestoreStats& st);

/// The ends of the links of `elements` that may take part in a fold (may_fold): the only
/// corners a folded cell can have. Appended to `suspects` (ascending, unique).
void find_fold_suspects(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& suspects);

/// Cells folded (a corner determinant <= 0, as cell_jacobian tests) among the cells with a corner
/// in `elements`; appends the 8 corners of each to `corners` (ascending, unique) and returns how
/// many cells folded.
Index find_folded_cells(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& corners);

/// Runs item(i) for every i in [0, items), in any order and on any threads (a backend's pool);
/// the callers merge what the items found into sorted, unique lists, so the result is the same.
using ParallelFor = std::function<void(std::int64_t items, const std::function<void(std::int64_t)>& item)>;

/// find_fold_suspects and find_folded_cells in chunks run by `parallel`: the same lists and
/// count (sorted, unique; a cell is tested once, in the chunk of bases it falls in).
void find_fold_suspects(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& suspects, const ParallelFor& parallel);
Index find_folded_cells(const Model& m, const std::vector<Index>& elements, const RestoreAccess& pos,
                        std::vector<Index>& corners, const ParallelFor& parallel);

/// Rounds of the fold guard that restore only the folded cells' corners before it restores every
/// link of the region (LinkRestorer::guard_folds).
inline constexpr int kFoldGuardRounds = 3;

class LinkRestorer {
 public:
  void init(const Model& m);
  /// The frame-end fold guard (docs/solver.md, "No fold"). `link_seeds`: the ends of the links
  /// outside their boxes (find_violations); a folded cell has a link that may fold (may_fold),
  /// which is outside its box too, so only the cells around those links are tested. Where cells are
  /// folded, the links around their corners
  /// are restored to their boxes, up to kFoldGuardRounds times; cells still folded then have every
  /// link of `link_seeds` restored, and links in their boxes cannot fold a cell (the shear cap).
  /// Nothing moves where no cell is folded. st.violated_links counts the cells found folded.
  void guard_folds(const Model& m, const BrickGrid& grid, const std::vector<Index>& link_seeds, RestoreAccess& pos,
                   const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st);
  /// The cap on each pass, in visits per lattice element (kRestoreVisitsPerElement; tests lower it).
  void set_visits_per_element(int visits) { visits_per_element_ = visits; }
  /// Lets the fold guard's search for folded cells and the restoration's two pass orders run on
  /// a backend's threads (the same result: each order has its own working state).
  void set_parallel(ParallelFor parallel) { parallel_ = std::move(parallel); }
  /// Restores consistency around `seeds` (ascending, unique linear indices; every element of the
  /// region out of its box or the wall, as find_violations lists them): every link and the
  /// wall, FIXED elements untouched. Bricks whose elements moved are flagged in `moved`;
  /// st.moved counts the elements moved.
  void restore(const Model& m, const BrickGrid& grid, const std::vector<Index>& seeds, RestoreAccess& pos,
               const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st);

 private:
  /// The working state of one pass order (copy k of coordinate b): copy 0 lowers to the upper
  /// bounds, then raises to the lower ones; copy 1 the other way round. The two share nothing,
  /// so their first two passes can run on two threads.
  struct Copy {
    std::vector<float> val;            ///< coordinate b, loaded from pos on first use in this axis
    std::vector<std::uint16_t> stamp;  ///< the axis (epoch_) val was loaded in
    std::vector<std::uint8_t> flags;   ///< kQueued, kChanged
    std::vector<Index> queue, changed, seeds;  ///< changed: each element once per axis
  };
  static constexpr std::uint8_t kQueued = 1, kChanged = 2;
  /// One pass over coordinate b of copy k, seeded with `seeds`; lists the elements whose value
  /// changed in the copy's `changed` (each once per axis).
  /// Returns false when the pass reached its cap (kRestoreVisitsPerElement) and stopped.
  bool pass(const Model& m, const RestoreAccess& pos, int b, int k, const Wall& wall, bool upper,
            const std::vector<Index>& seeds);
  /// Both pass orders of coordinate b from `seeds` (on two threads when `parallel`); each copy's
  /// second pass is seeded from its own first pass when the seeds are `every_violation` of the
  /// region, else from both. Returns false when a pass reached its cap.
  bool both_orders(const Model& m, const RestoreAccess& pos, int b, const Wall& wall, const std::vector<Index>& seeds,
                   bool every_violation, bool parallel);
  /// restore(), told whether the seeds are every element out of its box or the wall in the
  /// region (the check's seeds) or a part of them (the fold guard's corners).
  void restore(const Model& m, const BrickGrid& grid, const std::vector<Index>& seeds, bool every_violation,
               RestoreAccess& pos, const Wall& wall, std::vector<std::uint8_t>& moved, RestoreStats& st);
  /// The coordinate of element e in copy k, loaded from pos on first use in this axis.
  float& value(const RestoreAccess& pos, int b, int k, Index e) {
    Copy& c = copy_[k];
    if (c.stamp[e] != epoch_) {
      c.stamp[e] = epoch_;
      c.val[e] = pos.displacement(e)[b];
    }
    return c.val[e];
  }
  Copy copy_[2];
  std::uint16_t epoch_ = 0;
  std::vector<Index> pass_seeds_, moved_list_, guard_elements_, suspects_, folded_corners_;
  std::vector<Index> guard_moved_;             ///< elements the fold guard moved, over its rounds
  std::vector<Index>* record_moved_ = nullptr;  ///< set: restore() lists its moved elements here instead of counting
  std::vector<std::uint8_t> moved_flag_;
  int visits_per_element_ = kRestoreVisitsPerElement;
  ParallelFor parallel_;  ///< empty: the guard's search and the passes run on the calling thread
};

}  // namespace hpcm::solver
