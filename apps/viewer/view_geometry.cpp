#include "view_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hpcm::viewer {

const char* plane_name(Plane p) {
  switch (p) {
    case Plane::Axial: return "axial";
    case Plane::Coronal: return "coronal";
    case Plane::Sagittal: return "sagittal";
  }
  return "?";
}

PlaneAxes plane_axes(Plane p) {
  switch (p) {
    case Plane::Axial: return {0, 1, 2, -1.0f};
    case Plane::Coronal: return {0, 2, 1, 1.0f};
    case Plane::Sagittal: return {1, 2, 0, 1.0f};
  }
  return {0, 1, 2, -1.0f};
}

Vec2f to_display(Plane p, const std::array<double, 3>& spacing, Vec3 q) {
  const PlaneAxes a = plane_axes(p);
  return {q[a.u] * static_cast<float>(spacing[a.u]), a.v_sign * q[a.v] * static_cast<float>(spacing[a.v])};
}

Vec3 display_delta_to_lattice(Plane p, const std::array<double, 3>& spacing, Vec2f d) {
  const PlaneAxes a = plane_axes(p);
  Vec3 r{};
  r[a.u] = d.x / static_cast<float>(spacing[a.u]);
  r[a.v] = a.v_sign * d.y / static_cast<float>(spacing[a.v]);
  return r;
}

void ViewTransform::zoom_at(Vec2f px, float factor) {
  const Vec2f before = to_display(px);
  zoom = std::clamp(zoom * factor, 1e-3f, 1e4f);
  const Vec2f after = to_display(px);
  pan.x += before.x - after.x;
  pan.y += before.y - after.y;
}

ViewTransform fit_view(const Model& m, Plane p, float x0, float y0, float w, float h) {
  const PlaneAxes a = plane_axes(p);
  const int du[3] = {m.dims.x, m.dims.y, m.dims.z};
  // Extent of the rest lattice in display millimetres (vertex centres 0 .. N-1).
  const float eu = std::max(1.0f, float(du[a.u] - 1) * float(m.spacing[a.u]));
  const float ev = std::max(1.0f, float(du[a.v] - 1) * float(m.spacing[a.v]));
  ViewTransform t;
  t.x0 = x0;
  t.y0 = y0;
  t.w = std::max(1.0f, w);
  t.h = std::max(1.0f, h);
  t.zoom = 0.92f * std::min(t.w / eu, t.h / ev);
  t.pan = {0.5f * eu, a.v_sign * 0.5f * ev};
  return t;
}

int slice_count(const Model& m, Plane p) {
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  return d[plane_axes(p).n];
}

std::array<int, 2> slice_size(const Model& m, Plane p) {
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  const PlaneAxes a = plane_axes(p);
  return {d[a.u], d[a.v]};
}

Index slice_element(const Model& m, Plane p, int k, int a, int b) {
  const PlaneAxes ax = plane_axes(p);
  int c[3];
  c[ax.u] = a;
  c[ax.v] = b;
  c[ax.n] = k;
  return m.index(c[0], c[1], c[2]);
}

std::vector<std::uint32_t> slice_triangles(int nu, int nv) {
  std::vector<std::uint32_t> idx;
  if (nu < 2 || nv < 2) return idx;
  idx.reserve(static_cast<std::size_t>(nu - 1) * (nv - 1) * 6);
  for (int b = 0; b + 1 < nv; ++b) {
    for (int a = 0; a + 1 < nu; ++a) {
      const std::uint32_t v00 = static_cast<std::uint32_t>(a + nu * b);
      const std::uint32_t v10 = v00 + 1, v01 = v00 + static_cast<std::uint32_t>(nu), v11 = v01 + 1;
      idx.insert(idx.end(), {v00, v10, v11, v00, v11, v01});
    }
  }
  return idx;
}

std::vector<std::uint32_t> slice_lines(int nu, int nv) {
  std::vector<std::uint32_t> idx;
  for (int b = 0; b < nv; ++b)
    for (int a = 0; a < nu; ++a) {
      const std::uint32_t v = static_cast<std::uint32_t>(a + nu * b);
      if (a + 1 < nu) idx.insert(idx.end(), {v, v + 1});
      if (b + 1 < nv) idx.insert(idx.end(), {v, v + static_cast<std::uint32_t>(nu)});
    }
  return idx;
}

void slice_positions(const Model& m, Plane p, int k, const std::vector<Vec3>& disp, std::vector<Vec2f>& out) {
  const auto [nu, nv] = slice_size(m, p);
  out.resize(static_cast<std::size_t>(nu) * nv);
  for (int b = 0; b < nv; ++b)
    for (int a = 0; a < nu; ++a) {
      const Index i = slice_element(m, p, k, a, b);
      // X0 + u in float: enough for pixels.
      out[static_cast<std::size_t>(a) + static_cast<std::size_t>(nu) * b] =
          to_display(p, m.spacing, m.rest(i) + disp[static_cast<std::size_t>(i)]);
    }
}

Index pick_element(const Model& m, Plane p, int k, const std::vector<Vec2f>& verts, Vec2f d, float max_dist_mm) {
  const auto [nu, nv] = slice_size(m, p);
  float best = std::numeric_limits<float>::infinity();
  std::size_t best_v = 0;
  for (std::size_t v = 0; v < verts.size(); ++v) {
    const float dx = verts[v].x - d.x, dy = verts[v].y - d.y;
    const float q = dx * dx + dy * dy;
    if (q < best) {
      best = q;
      best_v = v;
    }
  }
  if (verts.empty() || !(std::sqrt(best) <= max_dist_mm)) return -1;
  const int a = static_cast<int>(best_v % static_cast<std::size_t>(nu));
  const int b = static_cast<int>(best_v / static_cast<std::size_t>(nu));
  (void)nv;
  return slice_element(m, p, k, a, b);
}

}  // namespace hpcm::viewer
