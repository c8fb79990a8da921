#include "solver/bricks.hpp"

namespace hpcm::solver {

void BrickGrid::dilate_to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out) const {
  out.clear();
  for (Index b = 0; b < count; ++b)
    if (flagged_or_face_neighbour(flags, b)) out.push_back(b);
}

void BrickGrid::to_list(const std::vector<std::uint8_t>& flags, std::vector<Index>& out) {
  out.clear();
  for (Index b = 0; b < static_cast<Index>(flags.size()); ++b)
    if (flags[b]) out.push_back(b);
}

}  // namespace hpcm::solver
