#pragma once
// The face-neighbour walk of the 6-connected lattice, written once for both backends and the
// references. The order -x, +x, -y, +y, -z, +z is part of the rules: sums over neighbours
// follow it, so results are reproducible bit for bit.
#include "hpcm/model.hpp"

namespace hpcm::solver {

/// Calls f(n, axis, side, lo, hi) for each face neighbour n of element i = (x, y, z) of a
/// nx*ny*nz lattice. side is +1 when i lies on the + side of n; lo and hi are the link's
/// elements on its - and + side (the link's limits are stored with lo).
template <class F>
HPCM_HD inline void for_each_face_neighbour(int nx, int ny, int nz, int x, int y, int z, Index i, F&& f) {
  const Index sy = nx, sz = static_cast<Index>(nx) * ny;
  if (x > 0) f(i - 1, 0, +1, i - 1, i);
  if (x + 1 < nx) f(i + 1, 0, -1, i, i + 1);
  if (y > 0) f(i - sy, 1, +1, i - sy, i);
  if (y + 1 < ny) f(i + sy, 1, -1, i, i + sy);
  if (z > 0) f(i - sz, 2, +1, i - sz, i);
  if (z + 1 < nz) f(i + sz, 2, -1, i, i + sz);
}

/// The walk on a host Model: f(n, axis, side, link limits).
template <class F>
inline void for_each_face_neighbour(const Model& m, int x, int y, int z, Index i, F&& f) {
  for_each_face_neighbour(m.dims.x, m.dims.y, m.dims.z, x, y, z, i,
                          [&](Index n, int axis, int side, Index lo, Index) { f(n, axis, side, m.link(axis, lo)); });
}

}  // namespace hpcm::solver
