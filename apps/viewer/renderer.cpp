#include "renderer.hpp"

#include <string>

#include "hpcm/types.hpp"

namespace hpcm::viewer {
namespace {

const char* kVertex = R"(#version 330 core
layout(location = 0) in vec2 a_pos;
layout(location = 1) in vec4 a_col;
uniform vec4 u_xform;   // display mm -> NDC: scale.xy, offset.zw
out vec4 v_col;
void main() {
  gl_Position = vec4(a_pos * u_xform.xy + u_xform.zw, 0.0, 1.0);
  v_col = a_col;
}
)";

const char* kFragment = R"(#version 330 core
in vec4 v_col;
uniform vec4 u_line;    // wire-frame colour (alpha 0: use the vertex colour)
out vec4 o_col;
void main() {
  o_col = u_line.a > 0.0 ? u_line : v_col;
}
)";

GLuint compile(GLenum type, const char* src) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {0};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    throw Error(std::string("OpenGL shader compilation failed: ") + log);
  }
  return s;
}

}  // namespace

SliceRenderer::~SliceRenderer() {
  for (Mesh& m : mesh_) {
    if (m.vao) glDeleteVertexArrays(1, &m.vao);
    const GLuint bufs[4] = {m.vbo_pos, m.vbo_col, m.ebo_tri, m.ebo_line};
    for (GLuint b : bufs)
      if (b) glDeleteBuffers(1, &b);
  }
  if (prog_) glDeleteProgram(prog_);
}

void SliceRenderer::init() {
  const GLuint vs = compile(GL_VERTEX_SHADER, kVertex);
  const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragment);
  prog_ = glCreateProgram();
  glAttachShader(prog_, vs);
  glAttachShader(prog_, fs);
  glLinkProgram(prog_);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(prog_, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {0};
    glGetProgramInfoLog(prog_, sizeof log, nullptr, log);
    throw Error(std::string("OpenGL program link failed: ") + log);
  }
  loc_xform_ = glGetUniformLocation(prog_, "u_xform");
  loc_line_ = glGetUniformLocation(prog_, "u_line");
  for (Mesh& m : mesh_) {
    glGenVertexArrays(1, &m.vao);
    glGenBuffers(1, &m.vbo_pos);
    glGenBuffers(1, &m.vbo_col);
    glGenBuffers(1, &m.ebo_tri);
    glGenBuffers(1, &m.ebo_line);
    glBindVertexArray(m.vao);
    glBindBuffer(GL_ARRAY_BUFFER, m.vbo_pos);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(Vec2f), nullptr);
    glBindBuffer(GL_ARRAY_BUFFER, m.vbo_col);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(Rgba), nullptr);
    glBindVertexArray(0);
  }
  glBindBuffer(GL_ARRAY_BUFFER, 0);
}

void SliceRenderer::upload_positions(int slot, int nu, int nv, const std::vector<Vec2f>& verts) {
  Mesh& m = mesh_.at(static_cast<std::size_t>(slot));
  glBindVertexArray(m.vao);
  if (m.nu != nu || m.nv != nv) {
    const auto tri = slice_triangles(nu, nv);
    const auto lines = slice_lines(nu, nv);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ebo_tri);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(tri.size() * sizeof(std::uint32_t)), tri.data(),
                 GL_STATIC_DRAW);
    m.tri_count = static_cast<GLsizei>(tri.size());
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ebo_line);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(lines.size() * sizeof(std::uint32_t)),
                 lines.data(), GL_STATIC_DRAW);
    m.line_count = static_cast<GLsizei>(lines.size());
    m.nu = nu;
    m.nv = nv;
  }
  glBindBuffer(GL_ARRAY_BUFFER, m.vbo_pos);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(verts.size() * sizeof(Vec2f)), verts.data(), GL_STREAM_DRAW);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  glBindVertexArray(0);
}

void SliceRenderer::upload_colours(int slot, const std::vector<Rgba>& cols) {
  Mesh& m = mesh_.at(static_cast<std::size_t>(slot));
  glBindVertexArray(m.vao);
  glBindBuffer(GL_ARRAY_BUFFER, m.vbo_col);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(cols.size() * sizeof(Rgba)), cols.data(), GL_STREAM_DRAW);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  glBindVertexArray(0);
}

void SliceRenderer::draw(int slot, const ViewTransform& t, float sx, float sy, float win_h, bool wire) {
  Mesh& m = mesh_.at(static_cast<std::size_t>(slot));
  if (m.tri_count == 0) return;
  const GLint vx = static_cast<GLint>(t.x0 * sx), vy = static_cast<GLint>((win_h - t.y0 - t.h) * sy);
  const GLsizei vw = static_cast<GLsizei>(t.w * sx), vh = static_cast<GLsizei>(t.h * sy);
  glViewport(vx, vy, vw, vh);
  glEnable(GL_SCISSOR_TEST);
  glScissor(vx, vy, vw, vh);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glUseProgram(prog_);
  const float kx = 2.0f * t.zoom / t.w, ky = 2.0f * t.zoom / t.h;
  glUniform4f(loc_xform_, kx, ky, -kx * t.pan.x, -ky * t.pan.y);
  glUniform4f(loc_line_, 0, 0, 0, 0);
  glBindVertexArray(m.vao);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ebo_tri);
  glDrawElements(GL_TRIANGLES, m.tri_count, GL_UNSIGNED_INT, nullptr);
  if (wire && m.line_count > 0) {
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUniform4f(loc_line_, 0.35f, 0.75f, 1.0f, 0.35f);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ebo_line);
    glDrawElements(GL_LINES, m.line_count, GL_UNSIGNED_INT, nullptr);
    glDisable(GL_BLEND);
  }
  glBindVertexArray(0);
  glUseProgram(0);
  glDisable(GL_SCISSOR_TEST);
}

Offscreen::~Offscreen() {
  if (rb_) glDeleteRenderbuffers(1, &rb_);
  if (fbo_) glDeleteFramebuffers(1, &fbo_);
}

void Offscreen::bind(int w, int h) {
  if (w != w_ || h != h_ || !fbo_) {
    if (rb_) glDeleteRenderbuffers(1, &rb_);
    if (fbo_) glDeleteFramebuffers(1, &fbo_);
    glGenFramebuffers(1, &fbo_);
    glGenRenderbuffers(1, &rb_);
    glBindRenderbuffer(GL_RENDERBUFFER, rb_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb_);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      glBindFramebuffer(GL_FRAMEBUFFER, 0);
      throw Error("OpenGL: cannot create a " + std::to_string(w) + "x" + std::to_string(h) + " off-screen framebuffer for " +
                  what_);
    }
    w_ = w;
    h_ = h;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
}

void Offscreen::blit_to(GLuint target) const {
  glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, target);
  glBlitFramebuffer(0, 0, w_, h_, 0, 0, w_, h_, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  glBindFramebuffer(GL_FRAMEBUFFER, target);
}

Image Offscreen::read() const {
  Image img;
  img.width = w_;
  img.height = h_;
  std::vector<std::uint8_t> rgba(static_cast<std::size_t>(w_) * h_ * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, w_, h_, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  img.rgb.resize(static_cast<std::size_t>(w_) * h_ * 3);
  for (int y = 0; y < h_; ++y) {
    const std::uint8_t* src = rgba.data() + static_cast<std::size_t>(h_ - 1 - y) * w_ * 4;  // bottom-up
    std::uint8_t* dst = img.rgb.data() + static_cast<std::size_t>(y) * w_ * 3;
    for (int x = 0; x < w_; ++x) {
      dst[3 * x + 0] = src[4 * x + 0];
      dst[3 * x + 1] = src[4 * x + 1];
      dst[3 * x + 2] = src[4 * x + 2];
    }
  }
  return img;
}

}  // namespace hpcm::viewer
