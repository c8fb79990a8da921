#include "solver/schedule.hpp"

#include <cmath>
#include <limits>

#include <algorithm>

namespace hpcm::solver {

float bucket_width(const Model& m) {
  float d = std::numeric_limits<float>::infinity();
  const int dims[3] = {m.dims.x, m.dims.y, m.dims.z};
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 2) continue;
    for (Index i = 0; i < m.size(); ++i) {
      const Int3 c = m.coords(i);
      const int ca[3] = {c.x, c.y, c.z};
      if (ca[a] + 1 < dims[a]) d = std::min(d, m.link(a, i).w);
    }
  }
  return std::isfinite(d) ? d : 1.0f;
}

}  // namespace hpcm::solver
