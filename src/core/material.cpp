#include "hpcm/material.hpp"

#include <cmath>
#include <sstream>

namespace hpcm {

void MaterialTable::validate() const {
  if (points.size() < 2)
    throw Error("material.points: need at least 2 control points, got " + std::to_string(points.size()));
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto& p = points[k];
    std::ostringstream key;
    key << "material.points[" << k << "]";
    if (k > 0 && !(p.hu > points[k - 1].hu)) {
      std::ostringstream m;
      m << key.str() << ".hu = " << p.hu << " must be greater than the previous point's hu " << points[k - 1].hu;
      throw Error(m.str());
    }
  }
}

namespace {
// Piecewise-linear interpolation of f over the control points, constant outside.
template <class F>
float interpolate(const std::vector<MaterialPoint>& pts, float hu, F f) {
  if (hu <= pts.front().hu) return f(pts.front());
  if (hu >= pts.back().hu) return f(pts.back());
  for (std::size_t k = 1; k < pts.size(); ++k)
    if (hu <= pts[k].hu) {
      const float u = (hu - pts[k - 1].hu) / (pts[k].hu - pts[k - 1].hu);
      return f(pts[k - 1]) + u * (f(pts[k]) - f(pts[k - 1]));
    }
  return f(pts.back());
}
}  // namespace

float MaterialTable::tau(float hu) const {
  // Log space: tolerances span two decades from bone to air.
  return std::exp(interpolate(points, hu, [](const MaterialPoint& p) { return std::log(p.tau); }));
}
float MaterialTable::w(float hu) const {
  return interpolate(points, hu, [](const MaterialPoint& p) { return p.w; });
}
LinkLimits MaterialTable::link(float hu_a, float hu_b) const { return link_at(0.5f * (hu_a + hu_b)); }

}  // namespace hpcm
