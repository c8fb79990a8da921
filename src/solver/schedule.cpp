#include "solver/schedule.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "hpcm/state.hpp"

namespace hpcm::solver {

float bucket_width(const Model& m, const std::vector<std::uint8_t>& still) {
  const bool some_still = !still.empty();
  float d = std::numeric_limits<float>::infinity();
  const int dims[3] = {m.dims.x, m.dims.y, m.dims.z};
  const Index stride[3] = {1, m.dims.x, static_cast<Index>(m.dims.x) * m.dims.y};
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 2) continue;
    for (Index i = 0; i < m.size(); ++i) {
      const Int3 c = m.coords(i);
      const int ca[3] = {c.x, c.y, c.z};
      if (ca[a] + 1 >= dims[a]) continue;
      if (some_still && (still[static_cast<std::size_t>(i)] || still[static_cast<std::size_t>(i + stride[a])])) continue;
      d = std::min(d, m.link(a, i).w);
    }
  }
  return std::isfinite(d) ? d : 1.0f;
}

void BucketWidth::reset(const Model& m) {
  still_.clear();
  known_ = false;
  width_ = bucket_width(m);
}

bool BucketWidth::update(const Model& m, const std::vector<Index>& fixed, const std::vector<std::uint8_t>& flags) {
  // The width depends on the still entries alone: a link between two elements that are not
  // FIXED has no still end, so it counts whatever the grabbed part of the set is. (A grabbed
  // element's links count too, though the wave only crosses them from time 0.)
  std::vector<Index> still;
  still.reserve(fixed.size());
  for (std::size_t k = 0; k < fixed.size(); ++k)
    if (!(flags[k] & kGrabbed)) still.push_back(fixed[k]);
  return update(m, still);
}

bool BucketWidth::update(const Model& m, const std::vector<Index>& still) {
  if (known_ && still == still_) return false;
  still_ = still;
  known_ = true;
  std::vector<std::uint8_t> mark(static_cast<std::size_t>(m.size()), 0);
  for (Index e : still_) mark[static_cast<std::size_t>(e)] = 1;
  const float before = width_;
  width_ = bucket_width(m, mark);
  return width_ != before;
}

}  // namespace hpcm::solver
