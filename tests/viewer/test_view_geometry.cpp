// GL-free parts of hpcm-viewer: view axes, pixel mapping, slice mesh, picking, colours, PNG.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "colour.hpp"
#include "hpcm/hpcm.hpp"
#include "options.hpp"
#include "png_io.hpp"
#include "view_geometry.hpp"

using namespace hpcm;
using namespace hpcm::viewer;

namespace {

Model small_model(Int3 dims, std::array<double, 3> spacing = {1, 1, 1}) {
  PhantomOptions po;
  po.dims = dims;
  Volume v = make_phantom(po);
  v.spacing = spacing;
  Model m = build_model(v, Params{});
  m.spacing = spacing;
  return m;
}

}  // namespace

TEST(ViewerGeometry, PlaneAxesFollowRadiologicalLps) {
  // Axial: x to the right, anterior (y = 0) at the top.
  const std::array<double, 3> sp{2, 3, 4};
  Vec2f a0 = to_display(Plane::Axial, sp, {0, 0, 5}), a1 = to_display(Plane::Axial, sp, {1, 1, 5});
  EXPECT_FLOAT_EQ(a1.x - a0.x, 2.0f);
  EXPECT_FLOAT_EQ(a1.y - a0.y, -3.0f);  // posterior is lower on screen
  // Coronal: superior up.
  Vec2f c0 = to_display(Plane::Coronal, sp, {0, 7, 0}), c1 = to_display(Plane::Coronal, sp, {0, 7, 1});
  EXPECT_FLOAT_EQ(c1.y - c0.y, 4.0f);
  // Sagittal: anterior on the left, superior up.
  Vec2f s0 = to_display(Plane::Sagittal, sp, {3, 0, 0}), s1 = to_display(Plane::Sagittal, sp, {3, 1, 1});
  EXPECT_FLOAT_EQ(s1.x - s0.x, 3.0f);
  EXPECT_FLOAT_EQ(s1.y - s0.y, 4.0f);
  for (int p = 0; p < 3; ++p) {
    const Vec3 d = display_delta_to_lattice(static_cast<Plane>(p), sp, {6, 12});
    const Vec2f back = to_display(static_cast<Plane>(p), sp, d);
    EXPECT_NEAR(back.x, 6, 1e-5);
    EXPECT_NEAR(back.y, 12, 1e-5);
    EXPECT_EQ(d[plane_axes(static_cast<Plane>(p)).n], 0.0f);
  }
}

TEST(ViewerGeometry, PixelMappingInvertsAndZoomKeepsCursorPoint) {
  ViewTransform t;
  t.x0 = 100;
  t.y0 = 50;
  t.w = 400;
  t.h = 300;
  t.zoom = 2.5f;
  t.pan = {10, -20};
  const Vec2f d{13.5f, -7.25f};
  const Vec2f px = t.to_pixel(d);
  const Vec2f back = t.to_display(px);
  EXPECT_NEAR(back.x, d.x, 1e-4);
  EXPECT_NEAR(back.y, d.y, 1e-4);
  // The pan point is at the rectangle's centre.
  const Vec2f c = t.to_pixel(t.pan);
  EXPECT_FLOAT_EQ(c.x, 300);
  EXPECT_FLOAT_EQ(c.y, 200);
  const Vec2f cursor{180, 90};
  const Vec2f under = t.to_display(cursor);
  t.zoom_at(cursor, 1.7f);
  EXPECT_NEAR(t.zoom, 2.5f * 1.7f, 1e-5);
  const Vec2f under2 = t.to_display(cursor);
  EXPECT_NEAR(under2.x, under.x, 1e-3);
  EXPECT_NEAR(under2.y, under.y, 1e-3);
}

TEST(ViewerGeometry, FitViewShowsTheWholeLattice) {
  const Model m = small_model({20, 16, 12}, {1.5, 2.0, 3.0});
  for (int p = 0; p < 3; ++p) {
    const Plane pl = static_cast<Plane>(p);
    const ViewTransform t = fit_view(m, pl, 10, 20, 300, 200);
    const auto [nu, nv] = slice_size(m, pl);
    for (int b : {0, nv - 1})
      for (int a : {0, nu - 1}) {
        const Vec2f px = t.to_pixel(to_display(pl, m.spacing, m.rest(slice_element(m, pl, 0, a, b))));
        EXPECT_TRUE(t.contains(px)) << plane_name(pl) << " corner " << a << "," << b;
      }
  }
}

TEST(ViewerGeometry, SliceMeshConnectsNeighbours) {
  const auto tri = slice_triangles(5, 4);
  EXPECT_EQ(tri.size(), std::size_t(4 * 3 * 6));
  for (std::size_t k = 0; k < tri.size(); k += 3) {
    // Every triangle spans at most one cell: vertices differ by <= 1 in a and in b.
    for (int e = 0; e < 3; ++e) {
      const int u = int(tri[k + e]), v = int(tri[k + (e + 1) % 3]);
      EXPECT_LE(std::abs(u % 5 - v % 5), 1);
      EXPECT_LE(std::abs(u / 5 - v / 5), 1);
    }
  }
  EXPECT_EQ(slice_lines(5, 4).size(), std::size_t(2 * (4 * 4 + 5 * 3)));
  EXPECT_TRUE(slice_triangles(1, 4).empty());
}

TEST(ViewerGeometry, SliceElementsAreTheRightOnes) {
  const Model m = small_model({10, 9, 8});
  EXPECT_EQ(slice_count(m, Plane::Axial), 8);
  EXPECT_EQ(slice_count(m, Plane::Coronal), 9);
  EXPECT_EQ(slice_count(m, Plane::Sagittal), 10);
  EXPECT_EQ(slice_element(m, Plane::Axial, 3, 4, 5), m.index(4, 5, 3));
  EXPECT_EQ(slice_element(m, Plane::Coronal, 2, 4, 5), m.index(4, 2, 5));
  EXPECT_EQ(slice_element(m, Plane::Sagittal, 7, 4, 5), m.index(7, 4, 5));
}

TEST(ViewerGeometry, PickFindsTheDeformedElementUnderTheCursor) {
  const Model m = small_model({12, 12, 10}, {2, 2, 2});
  std::vector<Vec3> disp(static_cast<std::size_t>(m.size()));  // displacements from rest
  const Index moved = m.index(6, 3, 5);
  disp[static_cast<std::size_t>(moved)] = {0.0f, -2.6f, 0.0f};  // pulled anterior by 2.6 cells, to (6, 0.4, 5)
  std::vector<Vec2f> verts;
  slice_positions(m, Plane::Axial, 5, disp, verts);
  // The cursor at the element's *current* place picks it, not the element resting there.
  EXPECT_EQ(pick_element(m, Plane::Axial, 5, verts, to_display(Plane::Axial, m.spacing, {6.1f, 0.5f, 5}), 2.0f), moved);
  EXPECT_EQ(pick_element(m, Plane::Axial, 5, verts, to_display(Plane::Axial, m.spacing, {2.2f, 7.9f, 5}), 2.0f),
            m.index(2, 8, 5));
  // Far outside the lattice: nothing.
  EXPECT_EQ(pick_element(m, Plane::Axial, 5, verts, to_display(Plane::Axial, m.spacing, {-5, -5, 5}), 2.0f), -1);
}

TEST(ViewerColour, WindowTissueAndOverlay) {
  EXPECT_EQ(red(hu_grey(-1000, 40, 400)), 0);
  EXPECT_EQ(red(hu_grey(1000, 40, 400)), 255);
  EXPECT_NEAR(red(hu_grey(40, 40, 400)), 128, 1);
  for (int t = 0; t < 4; ++t)
    for (int u = t + 1; u < 4; ++u) EXPECT_NE(tissue_colour(t), tissue_colour(u));
  const Rgba base = rgba(100, 100, 100);
  EXPECT_EQ(blend_overlay(base, 0.0f, 1.0f, 0.9f), base);          // zero shows the base colour
  EXPECT_EQ(blend_overlay(base, std::nanf(""), 1.0f, 0.9f), base);  // NaN never paints
  EXPECT_NE(blend_overlay(base, 1.0f, 1.0f, 0.9f), base);
  EXPECT_EQ(overlay_map(2.0f), overlay_map(1.0f));                    // clamped
  EXPECT_GT(red(overlay_map(1.0f)), blue(overlay_map(1.0f)));        // hot end is red
  EXPECT_GT(blue(overlay_map(0.0f)), red(overlay_map(0.0f)));        // cold end is blue
}

TEST(ViewerColour, DisplacementOverlayMarksTheMovedElementOnly) {
  const Model m = small_model({12, 12, 10});
  std::vector<Vec3> disp(static_cast<std::size_t>(m.size()));  // displacements from rest
  const Index i = m.index(6, 6, 5);  // inside the phantom body (not air)
  ASSERT_NE(m.tissue[static_cast<std::size_t>(i)], 0);
  disp[static_cast<std::size_t>(i)].y -= 1.0f;
  ColourSettings s;
  s.overlay = Overlay::Displacement;
  s.overlay_max = 1.0f;
  std::vector<Rgba> with, without;
  slice_colours(m, Plane::Axial, 5, disp, {}, s, with);
  s.overlay = Overlay::None;
  slice_colours(m, Plane::Axial, 5, disp, {}, s, without);
  int differing = 0;
  for (std::size_t k = 0; k < with.size(); ++k) differing += with[k] != without[k];
  EXPECT_EQ(differing, 1);
  EXPECT_NE(with[6 + 12 * 6], without[6 + 12 * 6]);
  EXPECT_FLOAT_EQ(slice_overlay_max(m, Plane::Axial, 5, disp, {}, Overlay::Displacement, false), 1.0f);
  // The speed overlay: the change of displacement since the previous frame.
  std::vector<Vec3> prev = disp;
  prev[static_cast<std::size_t>(i)].y += 0.25f;
  EXPECT_FLOAT_EQ(slice_overlay_max(m, Plane::Axial, 5, disp, prev, Overlay::Speed, false), 0.25f);
}

TEST(ViewerPng, RoundTripAndClearErrors) {
  Image img;
  img.width = 7;
  img.height = 5;
  img.rgb.resize(7 * 5 * 3);
  for (std::size_t k = 0; k < img.rgb.size(); ++k) img.rgb[k] = static_cast<std::uint8_t>(k * 37 % 256);
  const auto path = (std::filesystem::temp_directory_path() / "hpcm_viewer_png_test.png").string();
  write_png(img, path);
  const Image back = read_png(path);
  EXPECT_EQ(back.width, 7);
  EXPECT_EQ(back.height, 5);
  EXPECT_EQ(back.rgb, img.rgb);
  std::filesystem::remove(path);
  EXPECT_THROW(read_png(path), Error);
  EXPECT_THROW(write_png(img, "/nonexistent-dir/x.png"), Error);
  Image bad = img;
  bad.rgb.pop_back();
  EXPECT_THROW(write_png(bad, path), Error);
}

TEST(ViewerOptions, Int3Parsing) {
  const Int3 d = parse_int3("96,96,64", "--phantom");
  EXPECT_EQ(d, (Int3{96, 96, 64}));
  EXPECT_THROW(parse_int3("96,96", "--phantom"), Error);
  EXPECT_THROW(parse_int3("96,96,64,1", "--phantom"), Error);
  EXPECT_THROW(parse_int3("a,b,c", "--phantom"), Error);
}
