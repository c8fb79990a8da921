#pragma once
// GL-free geometry of the three slice views of hpcm-viewer: which lattice axes a view shows,
// how deformed element positions map to display millimetres and window pixels, the slice's
// connected quad mesh, and picking the element under the cursor. Kept free of OpenGL and
// ImGui so it is unit-tested (tests/viewer/test_view_geometry.cpp).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "hpcm/model.hpp"

namespace hpcm::viewer {

enum class Plane { Axial = 0, Coronal = 1, Sagittal = 2 };
inline constexpr int kPlaneCount = 3;
const char* plane_name(Plane p);  ///< "axial", "coronal", "sagittal"

/// Lattice axes shown by a view. Radiological display in LPS:
///   axial    (z fixed): right = +x (patient left on screen right), up = -y (anterior up)
///   coronal  (y fixed): right = +x, up = +z (superior up)
///   sagittal (x fixed): right = +y (anterior on the left), up = +z
struct PlaneAxes {
  int u;         ///< lattice axis shown left -> right
  int v;         ///< lattice axis shown bottom -> top (with v_sign)
  int n;         ///< normal axis (the slice index runs along it)
  float v_sign;  ///< +1 or -1
};
PlaneAxes plane_axes(Plane p);

struct Vec2f {
  float x = 0, y = 0;
};

/// Display coordinates (millimetres in the view plane, u right, v up) of a lattice position.
Vec2f to_display(Plane p, const std::array<double, 3>& spacing, Vec3 lattice_pos);
/// Lattice displacement (the normal component is 0) of a display-space displacement.
Vec3 display_delta_to_lattice(Plane p, const std::array<double, 3>& spacing, Vec2f d_display);

/// Maps display millimetres to window pixels (origin top-left, y down) for one view rectangle.
struct ViewTransform {
  float x0 = 0, y0 = 0, w = 1, h = 1;  ///< view rectangle in window pixels
  float zoom = 1;                      ///< pixels per millimetre
  Vec2f pan;                           ///< display point shown at the rectangle's centre

  Vec2f to_pixel(Vec2f d) const { return {x0 + 0.5f * w + (d.x - pan.x) * zoom, y0 + 0.5f * h - (d.y - pan.y) * zoom}; }
  Vec2f to_display(Vec2f px) const { return {pan.x + (px.x - x0 - 0.5f * w) / zoom, pan.y - (px.y - y0 - 0.5f * h) / zoom}; }
  bool contains(Vec2f px) const { return px.x >= x0 && px.x < x0 + w && px.y >= y0 && px.y < y0 + h; }
  /// Zoom by `factor` keeping the display point under pixel `px` fixed.
  void zoom_at(Vec2f px, float factor);
};

/// A transform that shows the whole rest lattice of `m` in the rectangle with a small margin.
ViewTransform fit_view(const Model& m, Plane p, float x0, float y0, float w, float h);

/// Number of slices along the view's normal axis.
int slice_count(const Model& m, Plane p);
/// Size of a slice (vertices along u and v).
std::array<int, 2> slice_size(const Model& m, Plane p);
/// Element index of slice vertex (a, b) of slice k (a along u, b along v).
Index slice_element(const Model& m, Plane p, int k, int a, int b);

/// Triangle indices of the slice's connected quad mesh: vertex (a, b) has index a + Nu*b and
/// each cell between four neighbouring elements is two triangles.
std::vector<std::uint32_t> slice_triangles(int nu, int nv);
/// Line-list indices of the mesh edges (for the optional wire-frame).
std::vector<std::uint32_t> slice_lines(int nu, int nv);

/// Display positions of every vertex of slice k (deformed: rest plus the displacements `disp`).
void slice_positions(const Model& m, Plane p, int k, const std::vector<Vec3>& disp, std::vector<Vec2f>& out);

/// The slice element nearest to display point `d` among the deformed vertices `verts` (as
/// filled by slice_positions). Returns -1 when the nearest one is farther than `max_dist_mm`
/// (the cursor is not over the mesh).
Index pick_element(const Model& m, Plane p, int k, const std::vector<Vec2f>& verts, Vec2f d, float max_dist_mm);

}  // namespace hpcm::viewer
