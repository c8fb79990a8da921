#pragma once
// The propagation schedule's bucket width, shared by both backends.
#include <cstdint>
#include <vector>

#include "hpcm/model.hpp"

namespace hpcm::solver {

/// Bucket width of the bucketed propagation: the smallest time penalty w of the links the wave
/// can cross (w > 0 is validated), 1 for a lattice without such links. Every crossed link then
/// has w >= the width, so each bucket's candidate times come from elements final in earlier
/// buckets (docs/solver.md). `still` (element order, may be empty: none) marks FIXED elements
/// that do not start the wave, the anchors: the wave never enters them and they push nothing,
/// so their links do not count. Without it every link counts.
float bucket_width(const Model& m, const std::vector<std::uint8_t>& still = {});

/// The bucket width of the current FIXED set, recomputed (O(elements)) only when its entries
/// that do not start the wave change: the anchors, fixed for a whole run, while the grabbed
/// elements change every frame of a pull. An element both anchored and grabbed (bone under the
/// tool) stays still for the width: the wave crosses its links only from time 0. Bone links
/// carry the smallest penalty (0.02 by default), so with bone anchored the buckets are several
/// times wider and the paper protocol's waves take four to five times fewer bucket passes
/// (docs/solver.md, "Bucket width").
class BucketWidth {
 public:
  /// Every link counts (no FIXED set yet): the model's smallest w.
  void reset(const Model& m);
  /// For the FIXED set `fixed` with its `flags` (kGrabbed: starts the wave). Returns whether the
  /// width changed.
  bool update(const Model& m, const std::vector<Index>& fixed, const std::vector<std::uint8_t>& flags);
  /// The same from the still entries alone (the FIXED set's entries without kGrabbed, in order).
  bool update(const Model& m, const std::vector<Index>& still);
  float value() const { return width_; }

 private:
  std::vector<Index> still_;  ///< FIXED, not grabbed, in the order given (compared as a whole)
  bool known_ = false;         ///< still_ is the set width_ was computed for
  float width_ = 1.0f;
};

}  // namespace hpcm::solver
