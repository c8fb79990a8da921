#pragma once
// OpenGL 3.3 core drawing of the slice meshes, and an off-screen framebuffer for screenshots.
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

/// Off-screen RGBA8 framebuffer: render into it, read it back, show it on the window.
class Capture {
 public:
  Capture() = default;
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;
  ~Capture();
  /// (Re)creates the framebuffer at w x h and binds it for drawing.
  void begin(int w, int h);
  /// Reads the framebuffer (top row first), copies it to the window's back buffer and
  /// binds the default framebuffer again.
  Image end();

 private:
  GLuint fbo_ = 0, rb_ = 0;
  int w_ = 0, h_ = 0;
};

}  // namespace hpcm::viewer
