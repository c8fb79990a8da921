#pragma once
// How far the grab tool can pull (SPEC §4, "infeasible requests"). Gibson's boxes constrain
// each coordinate axis separately: along axis b every link (u, v = u + unit_a) demands
// u_v - u_u in [min_stretch, max_stretch] when a == b and in [-shear, shear] otherwise
// (displacements from rest, u = X - X0). FIXED elements
// (anchors at rest, the grabbed elements moving rigidly with the tool) can all be met by some
// placement of the free elements exactly when, on every axis, the displacement between a
// grabbed element and an anchor does not exceed the slack of the cheapest chain of links
// between them. The boundary box [-margin, N - 1 + margin] is a wall every element must stay
// inside, so it counts as an anchor too. The tool offsets that can be met therefore form an
// axis-aligned box, computed once per grab by Dijkstra searches over the link slack (the
// amount each link can stretch, compress or shear beyond its rest shape); limiting the tool
// is a per-axis clamp into that box (the closest feasible tool position).
#include <cstdint>
#include <utility>
#include <vector>

#include "hpcm/model.hpp"

namespace hpcm::solver {

struct ToolLimit {
  Vec3 lo{}, hi{};  ///< feasible tool offsets per axis: lo[b] <= offset[b] <= hi[b] (lo <= 0 <= hi when the grab is consistent)
  /// The closest feasible offset (per-axis clamp).
  Vec3 clamp(Vec3 offset) const;
  bool contains(Vec3 offset) const;
};

/// Feasible offsets of a grab: `grabbed` elements held at displacement `origin[k] + offset`
/// (origin: their displacements from rest when grabbed); `anchored`
/// flags (per element, non-zero = anchored at rest; grabbed elements are never anchors);
/// `margin` is the boundary margin. Throws hpcm::Error on size mismatches.
ToolLimit tool_limit(const Model& m, const std::vector<Index>& grabbed, const std::vector<Vec3>& origin,
                     const std::vector<std::uint8_t>& anchored, float margin);

/// The same limit, searched only as far as the offsets asked for need. A search that has
/// settled every element closer than distance D has shown that its bound is at least D, and
/// that is all the clamp needs while the offset stays below it; so a grab costs nothing up
/// front, and a pull of a few cells explores the tissue within a few cells' slack of the
/// grab, a frame at a time, not everything up to the limit. clamp() gives exactly what
/// ToolLimit::clamp of tool_limit() gives; limit() runs the searches to the end. Needs at
/// least one grabbed element. The searches' memory follows the region they explore. Holds a
/// reference to the model, which must outlive it.
class ToolLimitSearch {
 public:
  ToolLimitSearch(const Model& m, std::vector<Index> grabbed, const std::vector<Vec3>& origin,
                  std::vector<std::uint8_t> anchored, float margin);
  ~ToolLimitSearch();
  ToolLimitSearch(const ToolLimitSearch&) = delete;
  ToolLimitSearch& operator=(const ToolLimitSearch&) = delete;

  /// The closest feasible offset to `offset` (per-axis clamp into the feasible box).
  Vec3 clamp(Vec3 offset);
  /// The whole feasible box.
  ToolLimit limit();

 private:
  struct Direction;
  /// Runs the searches that cannot yet tell whether `offset` is feasible on their side.
  void settle_for(Vec3 offset);
  /// Runs each listed search (index into dirs_) up to its distance cap.
  void run(const std::vector<std::pair<int, double>>& work);
  void extend(Direction& d, double cap) const;
  const Model& m_;
  std::vector<Index> grabbed_;
  std::vector<std::uint8_t> is_grabbed_;  ///< per element
  std::vector<std::uint8_t> anchored_;    ///< per element
  float margin_;
  std::vector<Direction> dirs_;  ///< [axis * 2 + (0: upper bound, 1: lower bound)]
};

}  // namespace hpcm::solver
