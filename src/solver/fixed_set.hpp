#pragma once
// A control's FIXED set in its two parts: the entries that hold (anchors, the same for a whole
// run: tens of thousands of elements on a CT) and the grabbed ones (the tool, new every frame of
// a pull). A backend that keeps them apart installs a new control at the cost of the part that
// changed instead of the whole set.
#include <cstdint>
#include <vector>

#include "hpcm/state.hpp"
#include "hpcm/types.hpp"

namespace hpcm::solver {

struct FixedParts {
  struct Part {
    std::vector<Index> elements;
    std::vector<Vec3> targets;
    std::vector<std::uint8_t> flags;  ///< the control's flags of each entry (kGrabbed, kAnchor)
    bool operator==(const Part& o) const = default;
  };
  Part still;  ///< entries without kGrabbed, in the control's order
  Part tool;   ///< entries with kGrabbed, in the control's order

  /// Splits the FIXED set (entries of equal length, Control::validate). An element listed in
  /// both parts counts as grabbed: the tool's entries are installed after the still ones.
  static FixedParts split(const std::vector<Index>& fixed, const std::vector<Vec3>& targets,
                          const std::vector<std::uint8_t>& flags) {
    FixedParts s;
    for (std::size_t k = 0; k < fixed.size(); ++k) {
      Part& p = (flags[k] & kGrabbed) ? s.tool : s.still;
      p.elements.push_back(fixed[k]);
      p.targets.push_back(targets[k]);
      p.flags.push_back(flags[k]);
    }
    return s;
  }
};

}  // namespace hpcm::solver
