#include "hpcm/state.hpp"

#include <algorithm>
#include <limits>

#include "core/link_box.hpp"

namespace hpcm {

State State::rest(const Model& m) {
  State s;
  const Index n = m.size();
  s.pos.resize(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) s.pos[i] = m.rest(i);
  s.vel.assign(static_cast<std::size_t>(n), Vec3{});
  s.time.assign(static_cast<std::size_t>(n), std::numeric_limits<float>::infinity());
  s.flags.assign(static_cast<std::size_t>(n), 0);
  return s;
}

float max_link_violation(const Model& m, const std::vector<Vec3>& pos) {
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  const Index stride[3] = {1, nx, static_cast<Index>(nx) * ny};
  float worst = 0.0f;
#pragma omp parallel for schedule(static) reduction(max : worst)
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        const Index i = m.index(x, y, z);
        const int c[3] = {x, y, z};
        const int d[3] = {nx, ny, nz};
        for (int a = 0; a < 3; ++a)
          if (c[a] + 1 < d[a]) worst = std::max(worst, link_violation(pos[i], pos[i + stride[a]], m.link[a][i], a));
      }
  return worst;
}

}  // namespace hpcm
