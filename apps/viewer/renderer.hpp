#pragma once
// OpenGL 3.3 core drawing of the slice meshes, and off-screen framebuffers (cached views, screenshots).
#include <array>
#include <vector>

#include "colour.hpp"
#include "gl.hpp"
#include "png_io.hpp"
#include "view_geometry.hpp"

namespace hpcm::viewer {

class SliceRenderer {
 public:
  SliceRenderer() = default;
  SliceRenderer(const SliceRenderer&) = delete;
  SliceRenderer& operator=(const SliceRenderer&) = delete;
  ~SliceRenderer();

  /// Compiles the shaders and creates the buffers; throws hpcm::Error with the GL log.
  void init();
  /// Uploads the vertex positions of mesh `slot` (a Nu x Nv vertex grid; the index buffers are
  /// rebuilt only when the grid size changes).
  void upload_positions(int slot, int nu, int nv, const std::vector<Vec2f>& verts);
  /// Uploads the vertex colours of mesh `slot` (one per vertex, after upload_positions).
  void upload_colours(int slot, const std::vector<Rgba>& cols);
  /// Draws mesh `slot` into view rectangle `t` (window pixels); `fb_scale` = framebuffer
  /// pixels per window pixel; `win_h` window height. Optional wire-frame on top.
  void draw(int slot, const ViewTransform& t, float fb_scale_x, float fb_scale_y, float win_h, bool wire);

 private:
  struct Mesh {
    GLuint vao = 0, vbo_pos = 0, vbo_col = 0, ebo_tri = 0, ebo_line = 0;
    int nu = 0, nv = 0;
    GLsizei tri_count = 0, line_count = 0;
  };
  std::array<Mesh, 3> mesh_{};
  GLuint prog_ = 0;
  GLint loc_xform_ = -1, loc_line_ = -1;
};

/// Off-screen RGBA8 framebuffer: the slice views are drawn into one and kept until they change
/// (each display frame copies it to the window), and screenshots are drawn into another.
class Offscreen {
 public:
  explicit Offscreen(const char* what) : what_(what) {}
  Offscreen(const Offscreen&) = delete;
  Offscreen& operator=(const Offscreen&) = delete;
  ~Offscreen();
  /// (Re)creates the framebuffer at w x h if its size changed, and binds it for drawing.
  void bind(int w, int h);
  /// Copies it, pixel for pixel, into framebuffer `target` (0: the window's back buffer) and
  /// leaves `target` bound.
  void blit_to(GLuint target) const;
  /// Its pixels, top row first.
  Image read() const;
  GLuint id() const { return fbo_; }

 private:
  const char* what_;  // for the error message
  GLuint fbo_ = 0, rb_ = 0;
  int w_ = 0, h_ = 0;
};

}  // namespace hpcm::viewer
