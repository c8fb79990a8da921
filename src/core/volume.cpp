#include "hpcm/volume.hpp"

#include <algorithm>
#include <cmath>

namespace hpcm {

std::array<double, 3> Volume::index_to_physical(double i, double j, double k) const {
  const double s[3] = {i * spacing[0], j * spacing[1], k * spacing[2]};
  std::array<double, 3> p = origin;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) p[r] += direction[r * 3 + c] * s[c];
  return p;
}

void validate_volume(const Volume& v, const std::string& what) {
  if (v.dims.x < 1 || v.dims.y < 1 || v.dims.z < 1)
    throw Error(what + ": dimensions " + std::to_string(v.dims.x) + "x" + std::to_string(v.dims.y) + "x" +
                std::to_string(v.dims.z) + " must be >= 1 on every axis");
  if (v.hu.size() != v.size())
    throw Error(what + ": has " + std::to_string(v.hu.size()) + " values for " + std::to_string(v.size()) + " voxels");
  if (!v.body.empty() && v.body.size() != v.size())
    throw Error(what + ": body mask has " + std::to_string(v.body.size()) + " values for " + std::to_string(v.size()) +
                " voxels");
  for (int a = 0; a < 3; ++a)
    if (!(v.spacing[a] > 0) || !std::isfinite(v.spacing[a]))
      throw Error(what + ": spacing[" + std::to_string(a) + "] = " + std::to_string(v.spacing[a]) + " must be finite and > 0");
  for (std::size_t i = 0; i < v.hu.size(); ++i)
    if (!std::isfinite(v.hu[i]))
      throw Error(what + ": non-finite value at voxel " + std::to_string(i));
}

Volume downsample(const Volume& v, int f) {
  const int mind = std::min({v.dims.x, v.dims.y, v.dims.z});
  if (f < 1 || f > mind)
    throw Error("downsample factor " + std::to_string(f) + " is out of range [1, " + std::to_string(mind) +
                "] (the smallest volume dimension)");
  if (f == 1) return v;
  // Complete blocks only: on a regular grid every element sits at the centre of its block, and
  // a partial block at the upper border could not (its voxels' centre is off the grid).
  Volume o;
  o.dims = {v.dims.x / f, v.dims.y / f, v.dims.z / f};
  o.spacing = {v.spacing[0] * f, v.spacing[1] * f, v.spacing[2] * f};
  o.direction = v.direction;
  // The new voxel (0,0,0) is the centre of the first block: index (f-1)/2 of the input.
  const double c = (f - 1) / 2.0;
  o.origin = v.index_to_physical(c, c, c);
  o.hu.assign(o.size(), 0.0f);
  const double count = double(f) * f * f;
#pragma omp parallel for schedule(static)
  for (int z = 0; z < o.dims.z; ++z)
    for (int y = 0; y < o.dims.y; ++y)
      for (int x = 0; x < o.dims.x; ++x) {
        double sum = 0;
        for (int k = z * f; k < z * f + f; ++k)
          for (int j = y * f; j < y * f + f; ++j)
            for (int i = x * f; i < x * f + f; ++i) sum += v.at(i, j, k);
        o.hu[static_cast<std::size_t>(o.index(x, y, z))] = static_cast<float>(sum / count);
      }
  return o;
}

Volume crop(const Volume& v, Int3 lo, Int3 hi) {
  const int d[3] = {v.dims.x, v.dims.y, v.dims.z};
  const int l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; ++a)
    if (l[a] < 0 || h[a] > d[a] || l[a] >= h[a])
      throw Error("roi axis " + std::to_string(a) + ": [" + std::to_string(l[a]) + ", " + std::to_string(h[a]) +
                  ") must satisfy 0 <= lo < hi <= " + std::to_string(d[a]));
  Volume o;
  o.dims = {hi.x - lo.x, hi.y - lo.y, hi.z - lo.z};
  o.spacing = v.spacing;
  o.direction = v.direction;
  o.origin = v.index_to_physical(lo.x, lo.y, lo.z);
  o.hu.resize(o.size());
  for (int z = 0; z < o.dims.z; ++z)
    for (int y = 0; y < o.dims.y; ++y)
      for (int x = 0; x < o.dims.x; ++x) o.hu[static_cast<std::size_t>(o.index(x, y, z))] = v.at(x + lo.x, y + lo.y, z + lo.z);
  return o;
}

}  // namespace hpcm
