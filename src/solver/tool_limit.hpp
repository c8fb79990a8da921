#pragma once
// How far the grab tool can pull (SPEC §4, "infeasible requests"). Gibson's boxes constrain
// each coordinate axis separately: along axis b every link (u, v = u + unit_a) demands
// x_v - x_u in [min_d, max_d] when a == b and in [-shear, shear] otherwise. FIXED elements
// (anchors at rest, the grabbed elements moving rigidly with the tool) can all be met by some
// placement of the free elements exactly when, on every axis, the displacement between a
// grabbed element and an anchor does not exceed the slack of the cheapest chain of links
// between them. The boundary box [-margin, N - 1 + margin] is a wall every element must stay
// inside, so it counts as an anchor too. The tool offsets that can be met therefore form an
// axis-aligned box, computed once per grab by Dijkstra searches over the link slack (the
// amount each link can stretch, compress or shear beyond its rest shape); limiting the tool
// is a per-axis clamp into that box (the closest feasible tool position).
#include <vector>

#include "hpcm/model.hpp"

namespace hpcm::solver {

struct ToolLimit {
  Vec3 lo{}, hi{};  ///< feasible tool offsets per axis: lo[b] <= offset[b] <= hi[b] (lo <= 0 <= hi when the grab is consistent)
  /// The closest feasible offset (per-axis clamp).
  Vec3 clamp(Vec3 offset) const;
  bool contains(Vec3 offset) const;
};

/// Feasible offsets of a grab: `grabbed` elements held at `origin[k] + offset`; `anchored`
/// flags (per element, non-zero = anchored at rest; grabbed elements are never anchors);
/// `margin` is the boundary margin. Throws hpcm::Error on size mismatches.
ToolLimit tool_limit(const Model& m, const std::vector<Index>& grabbed, const std::vector<Vec3>& origin,
                     const std::vector<std::uint8_t>& anchored, float margin);

}  // namespace hpcm::solver
