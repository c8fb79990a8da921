#include "hpcm/state.hpp"

#include <algorithm>
#include <array>
#include <limits>

#include "core/link_box.hpp"
#include "core/parallel.hpp"

namespace hpcm {

State State::rest(const Model& m) {
  State s;
  const Index n = m.size();
  s.disp.assign(static_cast<std::size_t>(n), Vec3{});
  s.vel.assign(static_cast<std::size_t>(n), Vec3{});
  s.time.assign(static_cast<std::size_t>(n), std::numeric_limits<float>::infinity());
  s.flags.assign(static_cast<std::size_t>(n), 0);
  return s;
}

std::vector<Point3> positions(const Model& m, const std::vector<Vec3>& disp) {
  std::vector<Point3> out(disp.size());
  for (Index i = 0; i < static_cast<Index>(disp.size()); ++i) out[static_cast<std::size_t>(i)] = position_of(m, i, disp[static_cast<std::size_t>(i)]);
  return out;
}

float max_link_violation(const Model& m, const std::vector<Vec3>& disp) {
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  const Index stride[3] = {1, nx, static_cast<Index>(nx) * ny};
  const int parts = pass_parts(nz);
  std::vector<float> worst(static_cast<std::size_t>(parts), 0.0f);
  run_parts(nz, parts, [&](int part, int z0, int z1) {
    float w = 0.0f;
    for (int z = z0; z < z1; ++z)
      for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) {
          const Index i = m.index(x, y, z);
          const int c[3] = {x, y, z};
          const int d[3] = {nx, ny, nz};
          for (int a = 0; a < 3; ++a)
            if (c[a] + 1 < d[a]) w = std::max(w, link_violation(disp[i], disp[i + stride[a]], m.link(a, i), a));
        }
    worst[static_cast<std::size_t>(part)] = w;
  });
  return *std::max_element(worst.begin(), worst.end());
}

CellJacobianStats cell_jacobian(const Model& m, const std::vector<Vec3>& disp) {
  CellJacobianStats st;
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  if (nx < 2 || ny < 2 || nz < 2) return st;
  const Index sy = nx, sz = static_cast<Index>(nx) * ny;
  const int parts = pass_parts(nz - 1);
  std::vector<double> part_min(static_cast<std::size_t>(parts), 1.0);
  std::vector<Index> part_folded(static_cast<std::size_t>(parts), 0);
  run_parts(nz - 1, parts, [&](int part, int z0, int z1) {
    double min_det = 1.0;
    Index folded = 0;
    for (int z = z0; z < z1; ++z)
      for (int y = 0; y < ny - 1; ++y)
        for (int x = 0; x < nx - 1; ++x) {
          const Index base = m.index(x, y, z);
          double cell_min = 1e30;
          for (int k = 0; k < 2; ++k)
            for (int j = 0; j < 2; ++j)
              for (int i = 0; i < 2; ++i) {
                const Index c = base + i + j * sy + k * sz;
                // Edges to the corner's neighbours inside the cell, oriented along +x, +y, +z.
                const Vec3 u = disp[c];
                const double det = corner_determinant(i ? u - disp[c - 1] : disp[c + 1] - u, j ? u - disp[c - sy] : disp[c + sy] - u,
                                                      k ? u - disp[c - sz] : disp[c + sz] - u);
                cell_min = std::min(cell_min, det);
              }
          min_det = std::min(min_det, cell_min);
          if (cell_min <= 0.0) ++folded;
        }
    part_min[static_cast<std::size_t>(part)] = min_det;
    part_folded[static_cast<std::size_t>(part)] = folded;
  });
  double min_det = 1.0;
  Index folded = 0;
  for (int t = 0; t < parts; ++t) {
    min_det = std::min(min_det, part_min[static_cast<std::size_t>(t)]);
    folded += part_folded[static_cast<std::size_t>(t)];
  }
  st.min_det = static_cast<float>(min_det);
  st.folded = folded;
  st.cells = static_cast<Index>(nx - 1) * (ny - 1) * (nz - 1);
  return st;
}

}  // namespace hpcm
