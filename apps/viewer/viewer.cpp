#include "viewer.hpp"

#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "gl.hpp"
#include "renderer.hpp"

#ifdef HPCM_VIEWER_WITH_IO
#include "hpcm/io.hpp"
#endif
#ifdef HPCM_VIEWER_WITH_CONFIG
#include "hpcm/config.hpp"
#endif

namespace hpcm::viewer {
namespace {

std::string g_glfw_error;
void glfw_error(int code, const char* what) {
  g_glfw_error = std::string(what ? what : "unknown") + " (GLFW error " + std::to_string(code) + ")";
}

ImU32 im(Rgba c, int a = 255) { return IM_COL32(red(c), green(c), blue(c), a); }

ImU32 series_colour(int tissue) {
  switch (tissue) {
    case 0: return IM_COL32(150, 150, 160, 255);
    case 1: return IM_COL32(240, 200, 110, 255);
    case 2: return IM_COL32(230, 80, 70, 255);
    case 3: return IM_COL32(235, 235, 235, 255);
  }
  return IM_COL32(255, 0, 255, 255);
}

const ImU32 kPlaneColour[3] = {IM_COL32(90, 160, 255, 200), IM_COL32(110, 220, 110, 200), IM_COL32(255, 170, 60, 200)};

/// A multi-series line plot over the history (newest at the right edge).
void plot_series(const char* id, int series, int count, int capacity, const std::function<float(int, int)>& get,
                 const std::function<ImU32(int)>& colour, const std::function<const char*(int)>& name, ImVec2 size,
                 bool log_scale, const char* unit) {
  ImGui::PushID(id);
  const ImVec2 p0 = ImGui::GetCursorScreenPos();
  ImGui::InvisibleButton("plot", size);
  const ImVec2 p1(p0.x + size.x, p0.y + size.y);
  ImDrawList* dl = ImGui::GetWindowDrawList();
  dl->AddRectFilled(p0, p1, IM_COL32(18, 20, 26, 255));
  dl->AddRect(p0, p1, IM_COL32(80, 82, 95, 255));
  float hi = 0;
  for (int s = 0; s < series; ++s)
    for (int k = 0; k < count; ++k) {
      const float v = get(s, k);
      if (std::isfinite(v)) hi = std::max(hi, v);
    }
  const float top = hi > 0 ? hi * 1.1f : 1.0f;
  const float lo_log = std::log10(std::max(top * 1e-5f, 1e-9f)), hi_log = std::log10(top);
  auto ymap = [&](float v) {
    float t;
    if (log_scale) t = (std::log10(std::max(v, 1e-12f)) - lo_log) / std::max(hi_log - lo_log, 1e-6f);
    else t = v / top;
    t = std::clamp(t, 0.0f, 1.0f);
    return p1.y - 2 - t * (size.y - 22);  // the top 18 px hold the labels
  };
  std::vector<ImVec2> pts;
  const float dx = (size.x - 4) / float(std::max(capacity - 1, 1));
  for (int s = 0; s < series; ++s) {
    pts.clear();
    for (int k = 0; k < count; ++k) {
      const float x = p1.x - 2 - float(count - 1 - k) * dx;
      pts.push_back(ImVec2(x, ymap(get(s, k))));
    }
    if (pts.size() >= 2) dl->AddPolyline(pts.data(), static_cast<int>(pts.size()), colour(s), 0, 1.5f);
  }
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.3g %s%s", double(top), unit, log_scale ? " (log)" : "");
  dl->AddText(ImVec2(p0.x + 4, p0.y + 2), IM_COL32(200, 200, 200, 255), buf);
  float lx = p0.x + 4 + ImGui::CalcTextSize(buf).x + 14;
  for (int s = 0; s < series; ++s) {
    const char* n = name(s);
    dl->AddText(ImVec2(lx, p0.y + 2), colour(s), n);
    lx += ImGui::CalcTextSize(n).x + 10;
  }
  dl->AddLine(ImVec2(p0.x + 1, p0.y + 18), ImVec2(p1.x - 1, p0.y + 18), IM_COL32(50, 52, 62, 255));
  ImGui::PopID();
}

bool materials_differ(const Params& a, const Params& b) {
  if (a.tissue.t1 != b.tissue.t1 || a.tissue.t2 != b.tissue.t2 || a.tissue.t3 != b.tissue.t3) return true;
  if (a.material.points.size() != b.material.points.size()) return true;
  for (std::size_t i = 0; i < a.material.points.size(); ++i) {
    const auto &p = a.material.points[i], &q = b.material.points[i];
    if (p.hu != q.hu || p.tau != q.tau || p.w != q.w) return true;
  }
  return false;
}

}  // namespace

bool display_available() {
  const char* d = std::getenv("DISPLAY");
  const char* w = std::getenv("WAYLAND_DISPLAY");
  return (d && *d) || (w && *w);
}

// ------------------------------------------------------------------------------------------
// construction, simulation

Viewer::Viewer(const Options& o, Session s) : opt_(o), source_(std::move(s.source)), edit_(s.params) {
  scenario_ = std::move(s.scenario);
  layout_ = o.layout == "axial" ? Layout::Axial : o.layout == "coronal" ? Layout::Coronal
          : o.layout == "sagittal" ? Layout::Sagittal : Layout::All;
  hide_panel_ = o.hide_panel;
  wire_ = o.wire;
  running_ = !o.paused;
  colour_.base = o.colour == "tissue" ? BaseColour::Tissue : BaseColour::HuWindow;
  colour_.overlay = o.overlay == "speed" ? Overlay::Speed : o.overlay == "displacement" ? Overlay::Displacement : Overlay::None;
  colour_.level = o.level;
  colour_.width = o.window;
  auto_overlay_ = !(o.overlay_max > 0);
  if (o.overlay_max > 0) colour_.overlay_max = o.overlay_max;
  phantom_dims_[0] = s.model.dims.x;
  phantom_dims_[1] = s.model.dims.y;
  phantom_dims_[2] = s.model.dims.z;
  if (o.phantom) {
    phantom_seed_ = static_cast<int>(o.seed);
    phantom_noise_ = o.noise_hu;
  }
  if (!o.input.empty()) std::snprintf(volume_path_, sizeof volume_path_, "%s", o.input.c_str());
  if (!o.params.empty()) std::snprintf(params_path_, sizeof params_path_, "%s", o.params.c_str());
  if (!o.scenario.empty()) std::snprintf(scenario_path_, sizeof scenario_path_, "%s", o.scenario.c_str());
  load_downsample_ = o.downsample;
  cuda_ok_ = cuda_available(&cuda_why_);
  for (int p = 0; p < kPlaneCount; ++p) views_[p].plane = static_cast<Plane>(p);
  make_simulation(std::move(s.model), s.params, s.backend);
  // Explicit slice positions (validated against the lattice).
  const int dims[3] = {sim_->model().dims.x, sim_->model().dims.y, sim_->model().dims.z};
  const Plane by_axis[3] = {Plane::Sagittal, Plane::Coronal, Plane::Axial};
  const char* axis_name[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (o.slices[a] < 0) continue;
    if (o.slices[a] >= dims[a])
      throw Error(std::string("--slices: ") + axis_name[a] + " = " + std::to_string(o.slices[a]) + " is outside [0, " +
                  std::to_string(dims[a] - 1) + "]");
    views_[static_cast<int>(by_axis[a])].slice = o.slices[a];
  }
}

Viewer::~Viewer() {
  renderer_.reset();
  capture_.reset();
  if (imgui_ready_) {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
  if (win_) glfwDestroyWindow(win_);
  if (glfw_ready_) glfwTerminate();
}

void Viewer::make_simulation(Model m, const Params& p, BackendKind k) {
  player_.reset();
  sim_.reset();
  sim_ = std::make_unique<Simulation>(std::move(m), p, k);
  backend_ = k;
  edit_ = sim_->params();
  params_pending_ = false;
  prev_pos_.clear();
  hist_.clear();
  last_ = {};
  tool_ = {};
  tool_.radius = edit_.solver.grab_radius;
  make_player();
  default_slices();
  for (View& v : views_) v.user_moved = false;
}

void Viewer::make_player() {
  player_.reset();
  scenario_active_ = false;
  if (!scenario_) return;
  scenario_->validate(sim_->model());
  player_ = std::make_unique<ScenarioPlayer>(*scenario_, *sim_);
  scenario_active_ = true;
}

Index Viewer::reference_centre() const {
  const Model& m = sim_->model();
  if (scenario_ && !scenario_->grabs.empty()) {
    if (player_) return player_->centre_of(0);
    const auto& c = scenario_->grabs[0].centre;
    if (c) return m.index(c->x, c->y, c->z);
  }
  try {
    return paper_grab_centre(m);
  } catch (const Error&) {
    return -1;
  }
}

void Viewer::default_slices() {
  const Model& m = sim_->model();
  Int3 c{m.dims.x / 2, m.dims.y / 2, m.dims.z / 2};
  const Index g = reference_centre();
  if (g >= 0) c = m.coords(g);
  views_[static_cast<int>(Plane::Axial)].slice = c.z;
  // Coronal through the body centre: the paper pull is along y, so a coronal cut through the
  // grab point would show only out-of-plane motion.
  views_[static_cast<int>(Plane::Coronal)].slice = m.dims.y / 2;
  views_[static_cast<int>(Plane::Sagittal)].slice = c.x;
}

void Viewer::step_once() {
  prev_pos_ = sim_->state().pos;
  if (player_ && scenario_active_ && !player_->done()) last_ = player_->step();
  else last_ = sim_->step();
  Sample s;
  s.frame = last_.frame;
  s.speed = last_.mean_speed;
  s.chainmail = static_cast<float>(last_.chainmail_ms);
  s.inertia = static_cast<float>(last_.inertia_ms);
  s.snapshot = static_cast<float>(last_.snapshot_ms);
  s.total = static_cast<float>(last_.sim_total_ms);
  hist_.push_back(s);
  while (static_cast<int>(hist_.size()) > 2000) hist_.pop_front();
  track_tool();
}

void Viewer::track_tool() {
  if (sim_->grabbing()) {
    const Index c = sim_->grab_centre();
    if (!tool_.held || tool_.centre != c) {  // a grab started by the scenario
      tool_.centre = c;
      tool_.held = true;
      tool_.origin = sim_->position(c) - sim_->tool_offset();
      tool_.radius = sim_->params().solver.grab_radius;
      if (player_ && scenario_)
        for (std::size_t k = 0; k < scenario_->grabs.size(); ++k)
          if (player_->centre_of(k) == c && scenario_->grabs[k].radius > 0) tool_.radius = scenario_->grabs[k].radius;
    }
    tool_.pos = tool_.origin + sim_->tool_offset();
    tool_.shown = true;
  } else {
    tool_.held = false;
  }
}

void Viewer::reset() {
  sim_->reset();
  prev_pos_.clear();
  hist_.clear();
  last_ = {};
  tool_ = {};
  drag_view_ = -1;
  try {
    make_player();
  } catch (const Error& e) {
    scenario_.reset();
    message(e.what(), true);
  }
}

void Viewer::apply_params(bool force) {
  if (!params_pending_ && !force) return;
  try {
    edit_.validate();
  } catch (const Error& e) {
    param_error_ = e.what();
    params_pending_ = false;
    return;
  }
  param_error_.clear();
  params_pending_ = false;
  try {
    // Simulation::set_params keeps the state; it rebuilds the materials (and reloads the
    // backend) when thresholds, material points or anchors changed.
    const bool rebuild = materials_differ(edit_, sim_->params()) || edit_.solver.anchors != sim_->params().solver.anchors;
    sim_->set_params(edit_);
    if (rebuild) message("materials rebuilt");
  } catch (const Error& e) {
    param_error_ = e.what();
  }
}

void Viewer::set_mode(DampingMode m) {
  edit_.dynamics.mode = m;
  apply_params(true);
  message(std::string("damping mode: ") + damping_mode_name(m));
}

// ------------------------------------------------------------------------------------------
// window

void Viewer::open_window() {
  glfwSetErrorCallback(glfw_error);
  if (!glfwInit()) {
    const char* d = std::getenv("DISPLAY");
    throw Error(std::string("cannot open display '") + (d ? d : "") + "': " + g_glfw_error +
                "; set DISPLAY or run under xvfb-run");
  }
  glfw_ready_ = true;
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_RESIZABLE, opt_.scripted() ? GLFW_FALSE : GLFW_TRUE);
  const std::string title = "hpcm-viewer - " + source_;
  win_ = glfwCreateWindow(opt_.width, opt_.height, title.c_str(), nullptr, nullptr);
  if (!win_)
    throw Error("cannot create a " + std::to_string(opt_.width) + "x" + std::to_string(opt_.height) +
                " OpenGL 3.3 core window: " + g_glfw_error +
                " (with Mesa software rendering try LIBGL_ALWAYS_SOFTWARE=1)");
  glfwMakeContextCurrent(win_);
  glfwSwapInterval(opt_.scripted() ? 0 : 1);

  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini in the working directory; the layout is fixed
  ImGui::StyleColorsDark();
  ImGui::GetStyle().WindowRounding = 0;
  // Our key callback first: ImGui's backend chains to it. Presses are queued so a key tapped
  // during a slow simulation frame is not lost.
  glfwSetWindowUserPointer(win_, this);
  glfwSetKeyCallback(win_, key_callback);
  ImGui_ImplGlfw_InitForOpenGL(win_, true);
  ImGui_ImplOpenGL3_Init("#version 330 core");
  imgui_ready_ = true;

  renderer_ = std::make_unique<SliceRenderer>();
  renderer_->init();
  capture_ = std::make_unique<Capture>();
}

int Viewer::run() {
  open_window();
  return opt_.scripted() ? run_script() : run_interactive();
}

int Viewer::run_script() {
  int frames = opt_.frames;
  if (frames < 0) frames = scenario_ ? scenario_->frames : 0;
  hist_len_ = std::clamp(frames, 50, 2000);  // the plots span the whole scripted run
  // Two frames without stepping let ImGui settle its window sizes.
  frame(0, false, nullptr);
  frame(0, false, nullptr);
  if (!opt_.record.empty()) {
    std::filesystem::create_directories(opt_.record);
    Image img;
    char name[64];
    for (int f = 0; f < frames; ++f) {
      frame(1, true, &img);
      std::snprintf(name, sizeof name, "frame_%05d.png", f + 1);
      save_screenshot(img, (std::filesystem::path(opt_.record) / name).string());
      if (glfwWindowShouldClose(win_)) throw Error("window closed during --record");
    }
  } else {
    for (int f = 0; f < frames; ++f) {
      step_once();
      if ((f & 7) == 0) glfwPollEvents();
    }
  }
  Image img;
  frame(0, false, nullptr);
  frame(0, true, &img);
  if (!opt_.screenshot.empty()) save_screenshot(img, opt_.screenshot);
  if (!opt_.report.empty()) write_report(opt_.report, img.width, img.height);
  std::printf("hpcm-viewer: played %d frames on %s (%lld elements, %s)%s%s\n", sim_->frame(), source_.c_str(),
              static_cast<long long>(sim_->model().size()), damping_mode_name(sim_->params().dynamics.mode),
              opt_.screenshot.empty() ? "" : ", wrote ", opt_.screenshot.c_str());
  return 0;
}

int Viewer::run_interactive() {
  while (!glfwWindowShouldClose(win_)) {
    const bool cap = screenshot_request_;
    screenshot_request_ = false;
    Image img;
    frame(0, cap, cap ? &img : nullptr);
    if (cap) {
      char name[96];
      std::snprintf(name, sizeof name, "hpcm-viewer-%05d-%02d.png", sim_->frame(), shot_counter_++);
      try {
        save_screenshot(img, name);
      } catch (const Error& e) {
        message(e.what(), true);
      }
    }
  }
  return 0;
}

void Viewer::save_screenshot(const Image& img, const std::string& path) {
  write_png(img, path);
  message("wrote " + path);
}

void Viewer::message(const std::string& m, bool error) {
  message_ = m;
  message_error_ = error;
  if (error) std::fprintf(stderr, "hpcm-viewer: %s\n", m.c_str());
}

// ------------------------------------------------------------------------------------------
// one frame

void Viewer::frame(int steps, bool capture, Image* out) {
  if (!opt_.scripted() && !running_ && step_requests_ == 0 && drag_view_ < 0 && pan_view_ < 0)
    glfwWaitEventsTimeout(0.05);  // idle: do not spin the CPU
  else
    glfwPollEvents();
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  update_layout();
  if (!opt_.scripted()) {
    handle_input();
    steps = running_ ? steps_per_frame_ : 0;
    steps += step_requests_;
    step_requests_ = 0;
  }
  for (int i = 0; i < steps; ++i) step_once();
  if (!hide_panel_) draw_panel();
  // Threshold and material edits rebuild the materials: apply them once the widget is released.
  if (params_pending_ && !(materials_differ(edit_, sim_->params()) && ImGui::IsAnyItemActive())) apply_params(false);
  if (plots_in_cell_) draw_plots_window();
  draw_view_overlays();
  ImGui::Render();

  update_meshes();
  int fbw = 0, fbh = 0, ww = 0, wh = 0;
  glfwGetFramebufferSize(win_, &fbw, &fbh);
  glfwGetWindowSize(win_, &ww, &wh);
  const float sx = ww > 0 ? float(fbw) / float(ww) : 1.0f, sy = wh > 0 ? float(fbh) / float(wh) : 1.0f;
  if (capture) capture_->begin(fbw, fbh);
  glViewport(0, 0, fbw, fbh);
  glClearColor(0.06f, 0.065f, 0.08f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  for (int p = 0; p < kPlaneCount; ++p)
    if (views_[p].visible) renderer_->draw(p, views_[p].xf, sx, sy, float(wh), wire_);
  glViewport(0, 0, fbw, fbh);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  if (capture && out) *out = capture_->end();
  else if (capture) capture_->end();
  glfwSwapBuffers(win_);
}

void Viewer::update_layout() {
  const ImGuiIO& io = ImGui::GetIO();
  const float W = io.DisplaySize.x, H = io.DisplaySize.y;
  const float x0 = hide_panel_ ? 0.0f : std::min(panel_w_, W * 0.5f);
  const float aw = std::max(1.0f, W - x0), ah = std::max(1.0f, H);
  Rect cells[4];
  for (auto& v : views_) v.visible = false;
  plots_in_cell_ = false;
  auto place = [&](Plane p, Rect r) {
    View& v = views_[static_cast<int>(p)];
    v.visible = true;
    const bool moved = r.x != v.rect.x || r.y != v.rect.y || r.w != v.rect.w || r.h != v.rect.h;
    if (moved || v.xf.zoom <= 0) {
      if (v.user_moved) {
        v.xf.x0 = r.x;
        v.xf.y0 = r.y;
        v.xf.w = r.w;
        v.xf.h = r.h;
      } else {
        v.xf = fit_view(sim_->model(), p, r.x, r.y, r.w, r.h);
      }
      v.rect = r;
    }
  };
  if (layout_ == Layout::All) {
    const float cw = std::floor(aw / 2), ch = std::floor(ah / 2);
    cells[0] = {x0, 0, cw, ch};
    cells[1] = {x0 + cw, 0, aw - cw, ch};
    cells[2] = {x0, ch, cw, ah - ch};
    cells[3] = {x0 + cw, ch, aw - cw, ah - ch};
    place(Plane::Axial, cells[0]);
    place(Plane::Sagittal, cells[1]);
    place(Plane::Coronal, cells[2]);
    plots_rect_ = cells[3];
    plots_in_cell_ = true;
  } else {
    const Plane p = layout_ == Layout::Axial ? Plane::Axial : layout_ == Layout::Coronal ? Plane::Coronal : Plane::Sagittal;
    place(p, {x0, 0, aw, ah});
  }
}

void Viewer::fit_views() {
  for (View& v : views_) {
    v.user_moved = false;
    v.xf = fit_view(sim_->model(), v.plane, v.rect.x, v.rect.y, v.rect.w, v.rect.h);
  }
}

void Viewer::update_meshes() {
  const Model& m = sim_->model();
  const std::vector<Vec3>& pos = sim_->state().pos;
  float seen = 0;
  for (int p = 0; p < kPlaneCount; ++p) {
    View& v = views_[p];
    if (!v.visible) continue;
    v.slice = std::clamp(v.slice, 0, slice_count(m, v.plane) - 1);
    slice_positions(m, v.plane, v.slice, pos, v.verts);
    v.overlay_seen = slice_overlay_max(m, v.plane, v.slice, pos, prev_pos_, colour_.overlay, colour_.overlay_air);
    seen = std::max(seen, v.overlay_seen);
  }
  if (auto_overlay_ && colour_.overlay != Overlay::None) {
    // Automatic range: follows the largest value shown, decays slowly so the scale is stable.
    const float floor_v = colour_.overlay == Overlay::Speed ? 1e-3f : 1e-2f;
    colour_.overlay_max = std::max({seen, colour_.overlay_max * 0.98f, floor_v});
  }
  for (int p = 0; p < kPlaneCount; ++p) {
    View& v = views_[p];
    if (!v.visible) continue;
    slice_colours(m, v.plane, v.slice, pos, prev_pos_, colour_, v.cols);
    const auto sz = slice_size(m, v.plane);
    renderer_->upload(p, sz[0], sz[1], v.verts, v.cols);
  }
}

int Viewer::view_at(Vec2f px) const {
  for (int p = 0; p < kPlaneCount; ++p)
    if (views_[p].visible && views_[p].xf.contains(px)) return p;
  return -1;
}

// ------------------------------------------------------------------------------------------
// input

void Viewer::handle_input() {
  ImGuiIO& io = ImGui::GetIO();
  const Vec2f mp{io.MousePos.x, io.MousePos.y};
  const Model& m = sim_->model();
  if (!io.WantCaptureMouse) {
    const int v = view_at(mp);
    if (v >= 0 && ImGui::IsMouseClicked(0) && drag_view_ < 0) {
      View& view = views_[v];
      const Vec2f d = view.xf.to_display(mp);
      const PlaneAxes ax = plane_axes(view.plane);
      const float cell = float(std::max(m.spacing[ax.u], m.spacing[ax.v]));
      const Index e = pick_element(m, view.plane, view.slice, view.verts, d, 1.0f * cell);
      if (e >= 0) {
        const float r = edit_.solver.grab_radius;
        sim_->grab(e, r);
        if (scenario_active_) message("scenario stopped: the mouse took over the tool");
        scenario_active_ = false;
        tool_.centre = e;
        tool_.held = tool_.shown = true;
        tool_.origin = sim_->position(e);
        tool_.pos = tool_.origin;
        tool_.radius = r;
        drag_view_ = v;
        drag_start_ = d;
      }
    }
    if (v >= 0 && (ImGui::IsMouseClicked(1) || ImGui::IsMouseClicked(2))) pan_view_ = v;
    if (v >= 0 && io.MouseWheel != 0.0f) {
      views_[v].xf.zoom_at(mp, std::pow(1.15f, io.MouseWheel));
      views_[v].user_moved = true;
    }
  }
  if (drag_view_ >= 0) {
    View& view = views_[drag_view_];
    if (ImGui::IsMouseDown(0)) {
      const Vec2f d = view.xf.to_display(mp);
      const Vec3 off = display_delta_to_lattice(view.plane, m.spacing, {d.x - drag_start_.x, d.y - drag_start_.y});
      sim_->move_tool(off);
      tool_.pos = tool_.origin + off;
    } else {
      sim_->release();  // the tissue's residual motion plays out
      tool_.held = false;
      drag_view_ = -1;
    }
  }
  if (pan_view_ >= 0) {
    if (ImGui::IsMouseDown(1) || ImGui::IsMouseDown(2)) {
      View& view = views_[pan_view_];
      view.xf.pan.x -= io.MouseDelta.x / view.xf.zoom;
      view.xf.pan.y += io.MouseDelta.y / view.xf.zoom;
      if (io.MouseDelta.x != 0 || io.MouseDelta.y != 0) view.user_moved = true;
    } else {
      pan_view_ = -1;
    }
  }
  std::vector<int> keys;
  keys.swap(key_queue_);
  if (!io.WantCaptureKeyboard)
    for (int k : keys) handle_key(k);
}

void Viewer::key_callback(GLFWwindow* w, int key, int, int action, int) {
  auto* self = static_cast<Viewer*>(glfwGetWindowUserPointer(w));
  if (!self) return;
  if (action == GLFW_PRESS || (action == GLFW_REPEAT && key == GLFW_KEY_N)) self->key_queue_.push_back(key);
}

void Viewer::handle_key(int key) {
  switch (key) {
    case GLFW_KEY_SPACE: running_ = !running_; break;
    case GLFW_KEY_N:
      running_ = false;
      ++step_requests_;
      break;
    case GLFW_KEY_R:
      reset();
      message("reset to rest");
      break;
    case GLFW_KEY_S: screenshot_request_ = true; break;
    case GLFW_KEY_1: set_mode(DampingMode::None); break;
    case GLFW_KEY_2: set_mode(DampingMode::Simple); break;
    case GLFW_KEY_3: set_mode(DampingMode::Viscoelastic); break;
    case GLFW_KEY_F: fit_views(); break;
    case GLFW_KEY_T: colour_.base = colour_.base == BaseColour::Tissue ? BaseColour::HuWindow : BaseColour::Tissue; break;
    case GLFW_KEY_O: colour_.overlay = static_cast<Overlay>((static_cast<int>(colour_.overlay) + 1) % 3); break;
    case GLFW_KEY_W: wire_ = !wire_; break;
    case GLFW_KEY_H: hide_panel_ = !hide_panel_; break;
    case GLFW_KEY_ESCAPE: glfwSetWindowShouldClose(win_, GLFW_TRUE); break;
    default: break;
  }
}

// ------------------------------------------------------------------------------------------
// drawing on the views (tool, labels, slice lines, colour bar)

void Viewer::draw_view_overlays() {
  ImDrawList* dl = ImGui::GetBackgroundDrawList();
  const Model& m = sim_->model();
  const ImGuiIO& io = ImGui::GetIO();
  bool bar_drawn = false;
  for (int p = 0; p < kPlaneCount; ++p) {
    const View& v = views_[p];
    if (!v.visible) continue;
    const ImVec2 r0(v.xf.x0, v.xf.y0), r1(v.xf.x0 + v.xf.w, v.xf.y0 + v.xf.h);
    dl->PushClipRect(r0, r1, true);
    const PlaneAxes ax = plane_axes(v.plane);
    // Lines where the other two views cut this one (rest positions).
    for (int q = 0; q < kPlaneCount; ++q) {
      if (q == p) continue;
      const int n = plane_axes(static_cast<Plane>(q)).n;
      Vec3 a{}, b{};
      a[n] = b[n] = float(views_[q].slice);
      const int other = n == ax.u ? ax.v : ax.u;
      const int dims[3] = {m.dims.x, m.dims.y, m.dims.z};
      a[other] = -0.5f;
      b[other] = float(dims[other]) - 0.5f;
      const Vec2f pa = v.xf.to_pixel(to_display(v.plane, m.spacing, a));
      const Vec2f pb = v.xf.to_pixel(to_display(v.plane, m.spacing, b));
      dl->AddLine(ImVec2(pa.x, pa.y), ImVec2(pb.x, pb.y), kPlaneColour[q] & IM_COL32(255, 255, 255, 110), 1.0f);
    }
    // The grab tool.
    if (tool_.shown && !opt_.hide_tool) {
      const float sp = 0.5f * float(m.spacing[ax.u] + m.spacing[ax.v]);
      const float rpx = std::max(3.0f, tool_.radius * sp * v.xf.zoom);
      const Vec2f c = v.xf.to_pixel(to_display(v.plane, m.spacing, tool_.pos));
      const Vec2f o = v.xf.to_pixel(to_display(v.plane, m.spacing, tool_.origin));
      const bool in_plane = std::fabs(tool_.pos[ax.n] - float(v.slice)) <= tool_.radius + 0.5f;
      const int a = in_plane ? 255 : 110;
      if (tool_.held) {
        dl->AddLine(ImVec2(o.x, o.y), ImVec2(c.x, c.y), IM_COL32(0, 230, 255, a), 2.0f);
        dl->AddCircleFilled(ImVec2(o.x, o.y), 2.5f, IM_COL32(0, 230, 255, a));
        dl->AddCircleFilled(ImVec2(c.x, c.y), rpx, IM_COL32(0, 230, 255, a / 4), 32);
        dl->AddCircle(ImVec2(c.x, c.y), rpx, IM_COL32(0, 240, 255, a), 32, 2.5f);
        dl->AddLine(ImVec2(c.x - rpx - 6, c.y), ImVec2(c.x + rpx + 6, c.y), IM_COL32(0, 240, 255, a), 1.5f);
        dl->AddLine(ImVec2(c.x, c.y - rpx - 6), ImVec2(c.x, c.y + rpx + 6), IM_COL32(0, 240, 255, a), 1.5f);
      } else {
        dl->AddCircle(ImVec2(c.x, c.y), rpx, IM_COL32(255, 255, 255, a * 3 / 4), 32, 1.5f);
        dl->AddCircle(ImVec2(c.x, c.y), rpx + 3, IM_COL32(0, 0, 0, a / 2), 32, 1.0f);
        dl->AddText(ImVec2(c.x + rpx + 4, c.y - 7), IM_COL32(230, 230, 230, a), "released");
      }
    }
    // Radius preview under the cursor.
    if (!opt_.scripted() && drag_view_ < 0 && !io.WantCaptureMouse && v.xf.contains({io.MousePos.x, io.MousePos.y})) {
      const float sp = 0.5f * float(m.spacing[ax.u] + m.spacing[ax.v]);
      dl->AddCircle(io.MousePos, std::max(3.0f, edit_.solver.grab_radius * sp * v.xf.zoom), IM_COL32(0, 230, 255, 120), 32,
                    1.0f);
    }
    // Labels.
    char buf[128];
    const int count = slice_count(m, v.plane);
    std::snprintf(buf, sizeof buf, "%s  %c = %d / %d", plane_name(v.plane), "xyz"[ax.n], v.slice, count - 1);
    dl->AddText(ImVec2(r0.x + 6, r0.y + 4), kPlaneColour[p] | IM_COL32(0, 0, 0, 255), buf);
    static const char* letters[3][4] = {{"R", "L", "A", "P"}, {"R", "L", "S", "I"}, {"A", "P", "S", "I"}};
    const ImU32 lc = IM_COL32(200, 200, 200, 200);
    dl->AddText(ImVec2(r0.x + 6, 0.5f * (r0.y + r1.y) - 7), lc, letters[p][0]);
    dl->AddText(ImVec2(r1.x - 14, 0.5f * (r0.y + r1.y) - 7), lc, letters[p][1]);
    dl->AddText(ImVec2(0.5f * (r0.x + r1.x) - 4, r0.y + 20), lc, letters[p][2]);
    dl->AddText(ImVec2(0.5f * (r0.x + r1.x) - 4, r1.y - 18), lc, letters[p][3]);
    if (p == static_cast<int>(Plane::Axial) || (layout_ != Layout::All && !bar_drawn)) {
      const DampingMode dm = sim_->params().dynamics.mode;
      std::snprintf(buf, sizeof buf, "frame %d  %c  %s", sim_->frame(),
                    dm == DampingMode::None ? 'A' : dm == DampingMode::Simple ? 'B' : 'C', last_.deform ? "deform" : "idle");
      dl->AddText(ImVec2(r0.x + 6, r0.y + 20), IM_COL32(220, 220, 220, 230), buf);
    }
    // Colour bar of the overlay.
    if (colour_.overlay != Overlay::None && !bar_drawn) {
      bar_drawn = true;
      const float bw = 12, bh = std::min(140.0f, v.xf.h * 0.4f);
      const float bx = r1.x - bw - 40, by = r0.y + 28;
      const int steps = 32;
      for (int i = 0; i < steps; ++i) {
        const float t0 = float(i) / steps, t1 = float(i + 1) / steps;
        dl->AddRectFilledMultiColor(ImVec2(bx, by + bh * (1 - t1)), ImVec2(bx + bw, by + bh * (1 - t0)),
                                    im(overlay_map(t1)), im(overlay_map(t1)), im(overlay_map(t0)), im(overlay_map(t0)));
      }
      dl->AddRect(ImVec2(bx, by), ImVec2(bx + bw, by + bh), IM_COL32(200, 200, 200, 200));
      std::snprintf(buf, sizeof buf, "%.3g", double(colour_.overlay_max));
      dl->AddText(ImVec2(bx - 6, by - 16), IM_COL32(230, 230, 230, 255), buf);
      dl->AddText(ImVec2(bx + bw + 3, by + bh - 12), IM_COL32(230, 230, 230, 255), "0");
      dl->AddText(ImVec2(bx - 30, by + bh + 2), IM_COL32(230, 230, 230, 255),
                  colour_.overlay == Overlay::Speed ? "speed" : "|X-X0|");
    }
    dl->PopClipRect();
    dl->AddRect(r0, r1, IM_COL32(60, 62, 72, 255));
  }
}

// ------------------------------------------------------------------------------------------
// plots

void Viewer::draw_plots(float width, float h) {
  const int n = std::min(static_cast<int>(hist_.size()), hist_len_);
  const int off = static_cast<int>(hist_.size()) - n;
  ImGui::Text("mean speed per tissue (lattice units / frame), last %d frames", hist_len_);
  plot_series(
      "speed", kTissueCount, n, hist_len_, [&](int s, int k) { return hist_[static_cast<std::size_t>(off + k)].speed[s]; },
      series_colour, [](int s) { return tissue_name(s); }, ImVec2(width, h), log_speed_, "");
  ImGui::Text("stage times (ms)");
  static const char* stage[4] = {"ChainMail", "Inertia", "Snapshot", "SimTotal"};
  static const ImU32 stage_col[4] = {IM_COL32(90, 160, 255, 255), IM_COL32(240, 120, 200, 255),
                                     IM_COL32(140, 220, 120, 255), IM_COL32(240, 240, 240, 255)};
  plot_series(
      "times", 4, n, hist_len_,
      [&](int s, int k) {
        const Sample& x = hist_[static_cast<std::size_t>(off + k)];
        return s == 0 ? x.chainmail : s == 1 ? x.inertia : s == 2 ? x.snapshot : x.total;
      },
      [](int s) { return stage_col[s]; }, [](int s) { return stage[s]; }, ImVec2(width, h), false, "ms");
  double avg = 0;
  for (int k = 0; k < n; ++k) avg += hist_[static_cast<std::size_t>(off + k)].total;
  avg = n > 0 ? avg / n : 0;
  ImGui::Text("display %.1f fps | sim %.2f ms/frame (%.0f frames/s) | %lld elements", double(ImGui::GetIO().Framerate),
              avg, avg > 0 ? 1000.0 / avg : 0.0, static_cast<long long>(sim_->model().size()));
  ImGui::Text("last frame: %s, moved %lld, bricks %lld, sweeps %d/%d", last_.deform ? "deform" : "idle",
              static_cast<long long>(last_.moved_elements), static_cast<long long>(last_.active_bricks),
              last_.propagate_sweeps, last_.relax_sweeps);
}

void Viewer::draw_plots_window() {
  ImGui::SetNextWindowPos(ImVec2(plots_rect_.x, plots_rect_.y));
  ImGui::SetNextWindowSize(ImVec2(plots_rect_.w, plots_rect_.h));
  ImGui::Begin("Plots", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoBringToFrontOnFocus);
  const float w = ImGui::GetContentRegionAvail().x;
  const float h = std::max(60.0f, (ImGui::GetContentRegionAvail().y - 4 * ImGui::GetTextLineHeightWithSpacing()) / 2 - 6);
  draw_plots(w, h);
  ImGui::End();
}

// ------------------------------------------------------------------------------------------
// the control panel

void Viewer::draw_panel() {
  const ImGuiIO& io = ImGui::GetIO();
  ImGui::SetNextWindowPos(ImVec2(0, 0));
  ImGui::SetNextWindowSize(ImVec2(std::min(panel_w_, io.DisplaySize.x * 0.5f), io.DisplaySize.y));
  ImGui::Begin("hpcm-viewer", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoBringToFrontOnFocus);
  ImGui::PushItemWidth(-150);
  const Model& model = sim_->model();
  ImGui::TextWrapped("%s", source_.c_str());
  ImGui::Text("%d x %d x %d = %lld elements | frame %d", model.dims.x, model.dims.y, model.dims.z,
              static_cast<long long>(model.size()), sim_->frame());
  if (ImGui::Button(running_ ? "Pause (space)" : "Run (space)")) running_ = !running_;
  ImGui::SameLine();
  if (ImGui::Button("Step (n)")) {
    running_ = false;
    ++step_requests_;
  }
  ImGui::SameLine();
  if (ImGui::Button("Reset (r)")) reset();
  ImGui::SameLine();
  if (ImGui::Button("Shot (s)")) screenshot_request_ = true;
  ImGui::SliderInt("frames per redraw", &steps_per_frame_, 1, 10);
  ImGui::Text("grab: %s", sim_->grabbing() ? "held" : "none");
  if (sim_->grabbing()) {
    ImGui::SameLine();
    const Vec3 o = sim_->tool_offset();
    ImGui::Text("offset (%.2f, %.2f, %.2f)", double(o.x), double(o.y), double(o.z));
  }

  // --- backend ---
  const std::string& why = cuda_why_;
  if (cuda_ok_) {
    int b = backend_ == BackendKind::Cuda ? 1 : 0;
    if (ImGui::Combo("backend", &b, "cpu\0cuda\0")) {
      const BackendKind k = b ? BackendKind::Cuda : BackendKind::Cpu;
      if (k != backend_) {
        try {
          Model m = sim_->model();
          make_simulation(std::move(m), edit_, k);
          message(std::string("backend: ") + backend_name(k) + " (state reset)");
        } catch (const Error& e) {
          message(e.what(), true);
        }
      }
    }
  } else {
    ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
    ImGui::TextWrapped("backend: cpu (CUDA: %s)", why.empty() ? "not available" : why.c_str());
    ImGui::PopStyleColor();
  }

  if (ImGui::CollapsingHeader("Views", ImGuiTreeNodeFlags_DefaultOpen)) {
    int lay = static_cast<int>(layout_);
    if (ImGui::Combo("layout", &lay, "all three\0axial\0coronal\0sagittal\0")) layout_ = static_cast<Layout>(lay);
    int base = static_cast<int>(colour_.base);
    if (ImGui::Combo("colour (t)", &base, "HU window\0tissue class\0")) colour_.base = static_cast<BaseColour>(base);
    if (colour_.base == BaseColour::HuWindow) {
      ImGui::DragFloat("level (HU)", &colour_.level, 2.0f, -1500.0f, 3000.0f, "%.0f");
      ImGui::DragFloat("width (HU)", &colour_.width, 4.0f, 1.0f, 5000.0f, "%.0f", ImGuiSliderFlags_AlwaysClamp);
      if (ImGui::SmallButton("soft tissue")) colour_ = {colour_.base, 40, 400, colour_.overlay, colour_.overlay_max, colour_.overlay_opacity};
      ImGui::SameLine();
      if (ImGui::SmallButton("bone")) colour_ = {colour_.base, 400, 1800, colour_.overlay, colour_.overlay_max, colour_.overlay_opacity};
      ImGui::SameLine();
      if (ImGui::SmallButton("wide")) colour_ = {colour_.base, 0, 2000, colour_.overlay, colour_.overlay_max, colour_.overlay_opacity};
    }
    int ov = static_cast<int>(colour_.overlay);
    if (ImGui::Combo("overlay (o)", &ov, "none\0speed\0|X - X0|\0")) colour_.overlay = static_cast<Overlay>(ov);
    if (colour_.overlay != Overlay::None) {
      ImGui::Checkbox("auto range", &auto_overlay_);
      if (!auto_overlay_)
        ImGui::DragFloat("overlay max", &colour_.overlay_max, 0.01f, 1e-4f, 100.0f, "%.4f", ImGuiSliderFlags_AlwaysClamp | ImGuiSliderFlags_Logarithmic);
      ImGui::SliderFloat("opacity", &colour_.overlay_opacity, 0.0f, 1.0f, "%.2f", ImGuiSliderFlags_AlwaysClamp);
      ImGui::Checkbox("overlay on air", &colour_.overlay_air);
    }
    ImGui::Checkbox("mesh edges (w)", &wire_);
    for (int p = 0; p < kPlaneCount; ++p) {
      View& v = views_[p];
      const char* label[3] = {"axial z", "coronal y", "sagittal x"};
      ImGui::SliderInt(label[p], &v.slice, 0, slice_count(model, v.plane) - 1, "%d", ImGuiSliderFlags_AlwaysClamp);
    }
    if (ImGui::Button("Fit views (f)")) fit_views();
    ImGui::SameLine();
    if (ImGui::Button("Slices to grab point")) default_slices();
    ImGui::TextDisabled("left-drag: grab | right/middle-drag: pan | wheel: zoom");
  }

  if (!plots_in_cell_ && ImGui::CollapsingHeader("Plots", ImGuiTreeNodeFlags_DefaultOpen))
    draw_plots(ImGui::GetContentRegionAvail().x, 110);
  if (ImGui::CollapsingHeader("Plot settings")) {
    ImGui::SliderInt("history (frames)", &hist_len_, 50, 2000, "%d", ImGuiSliderFlags_AlwaysClamp);
    ImGui::Checkbox("log speed axis", &log_speed_);
  }

  bool changed = false;
  if (ImGui::CollapsingHeader("Grab tool and solver (SPEC 4)", ImGuiTreeNodeFlags_DefaultOpen)) {
    SolverParams& s = edit_.solver;
    changed |= ImGui::SliderFloat("grab radius (0,64]", &s.grab_radius, 0.5f, 16.0f, "%.2f", ImGuiSliderFlags_AlwaysClamp);
    int bs = s.brick_size == 4 ? 0 : s.brick_size == 16 ? 2 : 1;
    if (ImGui::Combo("brick size", &bs, "4\0" "8\0" "16\0")) {
      s.brick_size = bs == 0 ? 4 : bs == 2 ? 16 : 8;
      changed = true;
    }
    changed |= ImGui::SliderInt("relax sweeps K [0,256]", &s.relax_sweeps, 0, 256, "%d", ImGuiSliderFlags_AlwaysClamp);
    changed |= ImGui::InputFloat("relax threshold [0,1)", &s.relax_threshold, 1e-5f, 1e-4f, "%.6f");
    int an = static_cast<int>(s.anchors);
    if (ImGui::Combo("anchors", &an, "none\0bone\0border\0")) {
      s.anchors = static_cast<AnchorMode>(an);
      changed = true;
    }
    changed |= ImGui::InputInt("max propagation sweeps [1,1e7]", &s.max_propagation_sweeps, 100, 10000);
  }
  if (ImGui::CollapsingHeader("Dynamics (SPEC 5)", ImGuiTreeNodeFlags_DefaultOpen)) {
    DynamicsParams& d = edit_.dynamics;
    int mode = static_cast<int>(d.mode);
    if (ImGui::Combo("damping (1/2/3)", &mode, "A: none\0B: simple\0C: viscoelastic\0")) {
      d.mode = static_cast<DampingMode>(mode);
      changed = true;
    }
    changed |= ImGui::SliderFloat("alpha [0,1] (B)", &d.alpha, 0, 1, "%.3f", ImGuiSliderFlags_AlwaysClamp);
    changed |= ImGui::SliderFloat("b0 [0,1] (C)", &d.b0, 0, 1, "%.3f", ImGuiSliderFlags_AlwaysClamp);
    auto per_tissue = [&](const char* title, PerTissue& v, float lo, float hi, const char* f) {
      bool ch = false;
      ImGui::PushID(title);
      ImGui::TextUnformatted(title);
      for (int t = 0; t < kTissueCount; ++t) {
        const std::string l = std::string("  ") + tissue_name(t);
        ch |= ImGui::SliderFloat(l.c_str(), &v[t], lo, hi, f, ImGuiSliderFlags_AlwaysClamp);
      }
      ImGui::PopID();
      return ch;
    };
    changed |= per_tissue("b1 per class [0,1] (C)", d.b1, 0, 1, "%.3f");
    changed |= per_tissue("inverse mass per class (>= 0, one > 0)", d.inverse_mass, 0, 10, "%.3f");
    changed |= ImGui::SliderFloat("s_min [0,s_max]", &d.s_min, 0, 1, "%.3f", ImGuiSliderFlags_AlwaysClamp);
    changed |= ImGui::SliderFloat("s_max [s_min,1]", &d.s_max, 0, 1, "%.3f", ImGuiSliderFlags_AlwaysClamp);
    changed |= ImGui::InputFloat("dead zone [0,1)", &d.dead_zone, 1e-4f, 1e-3f, "%.5f");
    changed |= ImGui::SliderFloat("v_max (0,10]", &d.v_max, 0.001f, 10, "%.3f", ImGuiSliderFlags_AlwaysClamp | ImGuiSliderFlags_Logarithmic);
    changed |= ImGui::SliderFloat("beta [0,2]", &d.beta, 0, 2, "%.3f", ImGuiSliderFlags_AlwaysClamp);
    changed |= per_tissue("rho per class [0,2]", d.rho, 0, 2, "%.3f");
    changed |= ImGui::SliderFloat("margin [0,64]", &d.margin, 0, 64, "%.1f", ImGuiSliderFlags_AlwaysClamp);
    const PerTissue s = d.response_scale();
    ImGui::TextDisabled("response scale s: %.3f %.3f %.3f %.3f", double(s[0]), double(s[1]), double(s[2]), double(s[3]));
  }
  if (ImGui::CollapsingHeader("Tissue classes and material (SPEC 3)")) {
    TissueThresholds& t = edit_.tissue;
    ImGui::TextDisabled("t1 < t2 < t3 (HU); rebuilds the materials");
    changed |= ImGui::DragFloat("t1 air | skin&fat", &t.t1, 1.0f, -2000, 4000, "%.0f");
    changed |= ImGui::DragFloat("t2 skin&fat | muscle", &t.t2, 1.0f, -2000, 4000, "%.0f");
    changed |= ImGui::DragFloat("t3 muscle | bone", &t.t3, 1.0f, -2000, 4000, "%.0f");
    if (ImGui::SmallButton("paper thresholds")) {
      t = TissueThresholds{};
      changed = true;
    }
    ImGui::SameLine();
    if (ImGui::SmallButton("robust preset")) {
      t = TissueThresholds::robust_preset();
      changed = true;
    }
    ImGui::TextDisabled("control points: HU increasing, tau in (0,1], w in (0,100]");
    auto& pts = edit_.material.points;
    int remove = -1;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      ImGui::PushID(static_cast<int>(i));
      ImGui::PushItemWidth(70);
      changed |= ImGui::DragFloat("##hu", &pts[i].hu, 1.0f, -3000, 5000, "%.0f HU");
      ImGui::SameLine();
      changed |= ImGui::DragFloat("##tau", &pts[i].tau, 0.001f, 1e-4f, 1.0f, "tau %.4f", ImGuiSliderFlags_AlwaysClamp);
      ImGui::SameLine();
      changed |= ImGui::DragFloat("##w", &pts[i].w, 0.01f, 1e-3f, 100.0f, "w %.3f", ImGuiSliderFlags_AlwaysClamp);
      ImGui::PopItemWidth();
      ImGui::SameLine();
      if (pts.size() > 2 && ImGui::SmallButton("x")) remove = static_cast<int>(i);
      ImGui::PopID();
    }
    if (remove >= 0) {
      pts.erase(pts.begin() + remove);
      changed = true;
    }
    if (ImGui::SmallButton("add point")) {
      MaterialPoint q = pts.back();
      q.hu += 100;
      pts.push_back(q);
      changed = true;
    }
    ImGui::SameLine();
    if (ImGui::SmallButton("default material")) {
      edit_.material = MaterialTable{};
      changed = true;
    }
    ImGui::Text("elements: air %lld, skin&fat %lld, muscle %lld, bone %lld",
                static_cast<long long>(model.class_count[0]), static_cast<long long>(model.class_count[1]),
                static_cast<long long>(model.class_count[2]), static_cast<long long>(model.class_count[3]));
  }
  if (changed) params_pending_ = true;
  // Material and threshold edits rebuild the model: apply them when the widget is released.
  if (!param_error_.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", param_error_.c_str());

  if (ImGui::CollapsingHeader("Parameter file")) {
    ImGui::InputText("path##params", params_path_, sizeof params_path_);
#ifdef HPCM_VIEWER_WITH_CONFIG
    if (ImGui::Button("Save")) {
      try {
        const std::string text = config::params_to_toml(sim_->params());
        const std::string tmp = std::string(params_path_) + ".tmp";
        {
          std::ofstream f(tmp, std::ios::binary);
          f << text;
          if (!f) throw Error(std::string("cannot write ") + params_path_);
        }
        std::filesystem::rename(tmp, params_path_);
        message(std::string("saved ") + params_path_);
      } catch (const std::exception& e) {
        message(e.what(), true);
      }
    }
    ImGui::SameLine();
    if (ImGui::Button("Load")) {
      try {
        edit_ = config::load_params(params_path_);
        apply_params(true);
        if (param_error_.empty()) message(std::string("loaded ") + params_path_);
      } catch (const Error& e) {
        message(e.what(), true);
      }
    }
    ImGui::SameLine();
#else
    ImGui::TextDisabled("parameter files need hpcm built with toml++ (hpcm::config)");
#endif
    if (ImGui::Button("Defaults")) {
      edit_ = Params{};
      apply_params(true);
    }
  }

  if (ImGui::CollapsingHeader("Scenario")) {
    if (scenario_)
      ImGui::Text("%s: %d frames, %zu grab(s); %s, frame %d", scenario_->name.c_str(), scenario_->frames,
                  scenario_->grabs.size(), scenario_active_ ? (player_ && player_->done() ? "done" : "playing") : "stopped",
                  player_ ? player_->frame() : 0);
    else
      ImGui::TextDisabled("no scenario");
    ImGui::InputText("file##scenario", scenario_path_, sizeof scenario_path_);
    auto use = [&](std::optional<Scenario> s) {
      auto old = scenario_;
      scenario_ = std::move(s);
      try {
        reset();
        default_slices();
        running_ = true;
      } catch (const Error& e) {
        scenario_ = old;
        message(e.what(), true);
      }
    };
#ifdef HPCM_VIEWER_WITH_CONFIG
    if (ImGui::Button("Load + play")) {
      try {
        use(config::load_scenario(scenario_path_));
      } catch (const Error& e) {
        message(e.what(), true);
      }
    }
    ImGui::SameLine();
#endif
    if (ImGui::Button("Paper protocol")) use(Scenario::paper_protocol());
    ImGui::SameLine();
    if (ImGui::Button("Replay")) use(scenario_);
    ImGui::SameLine();
    if (ImGui::Button("None")) use(std::nullopt);
  }

  if (ImGui::CollapsingHeader("Data")) {
#ifdef HPCM_VIEWER_WITH_IO
    ImGui::InputText("volume", volume_path_, sizeof volume_path_);
    ImGui::SliderInt("down-sample", &load_downsample_, 1, 8, "%d", ImGuiSliderFlags_AlwaysClamp);
    if (ImGui::Button("Load volume")) {
      try {
        Volume v = io::read_volume(volume_path_);
        if (load_downsample_ > 1) v = downsample(v, load_downsample_);
        Model m = build_model(v, sim_->params());
        const std::string src = std::string(volume_path_) + (load_downsample_ > 1 ? " (f=" + std::to_string(load_downsample_) + ")" : "");
        make_simulation(std::move(m), sim_->params(), backend_);
        source_ = src;
        fit_views();
        message("loaded " + src);
      } catch (const Error& e) {
        message(e.what(), true);
      }
    }
#else
    ImGui::TextDisabled("volume files need hpcm built with ITK (hpcm::io)");
#endif
    ImGui::InputInt3("phantom NX,NY,NZ", phantom_dims_);
    ImGui::InputInt("seed", &phantom_seed_);
    ImGui::SliderFloat("noise (HU) [0,200]", &phantom_noise_, 0, 200, "%.1f", ImGuiSliderFlags_AlwaysClamp);
    if (ImGui::Button("Generate phantom")) {
      try {
        PhantomOptions po;
        po.dims = {phantom_dims_[0], phantom_dims_[1], phantom_dims_[2]};
        po.seed = static_cast<std::uint64_t>(std::max(phantom_seed_, 0));
        po.noise_hu = phantom_noise_;
        Model m = build_model(make_phantom(po), sim_->params());
        make_simulation(std::move(m), sim_->params(), backend_);
        char src[96];
        std::snprintf(src, sizeof src, "phantom %dx%dx%d (seed %d)", po.dims.x, po.dims.y, po.dims.z, phantom_seed_);
        source_ = src;
        fit_views();
        message(std::string("generated ") + src);
      } catch (const Error& e) {
        message(e.what(), true);
      }
    }
  }
  ImGui::PopItemWidth();
  if (!message_.empty()) {
    ImGui::Separator();
    if (message_error_) ImGui::TextColored(ImVec4(1, 0.45f, 0.4f, 1), "%s", message_.c_str());
    else ImGui::TextWrapped("%s", message_.c_str());
  }
  ImGui::End();
}

// ------------------------------------------------------------------------------------------
// report of the view geometry (scripted use)

void Viewer::write_report(const std::string& path, int image_w, int image_h) const {
  const Model& m = sim_->model();
  const ImGuiIO& io = ImGui::GetIO();
  const float sx = io.DisplaySize.x > 0 ? float(image_w) / io.DisplaySize.x : 1.0f;
  const float sy = io.DisplaySize.y > 0 ? float(image_h) / io.DisplaySize.y : 1.0f;
  std::ostringstream r;
  r << "# hpcm-viewer report: pixel coordinates are image pixels (x right, y down)\n";
  r << "image " << image_w << " " << image_h << "\n";
  r << "frames " << sim_->frame() << "\n";
  r << "dims " << m.dims.x << " " << m.dims.y << " " << m.dims.z << "\n";
  r << "elements " << m.size() << "\n";
  r << "mode " << damping_mode_name(sim_->params().dynamics.mode) << "\n";
  const Index g = tool_.shown ? tool_.centre : reference_centre();
  r << "grab_element " << g << "\n";
  for (int p = 0; p < kPlaneCount; ++p) {
    const View& v = views_[p];
    if (!v.visible) continue;
    const PlaneAxes ax = plane_axes(v.plane);
    const float cell = float(0.5 * (m.spacing[ax.u] + m.spacing[ax.v])) * v.xf.zoom * sx;
    r << "view " << plane_name(v.plane) << " " << v.xf.x0 * sx << " " << v.xf.y0 * sy << " " << v.xf.w * sx << " "
      << v.xf.h * sy << " slice " << v.slice << " px_per_cell " << cell << "\n";
    if (g >= 0) {
      const Vec2f q = v.xf.to_pixel(to_display(v.plane, m.spacing, m.rest(g)));
      r << "grab_px " << plane_name(v.plane) << " " << q.x * sx << " " << q.y * sy << "\n";
    }
    if (tool_.shown) {
      const Vec2f q = v.xf.to_pixel(to_display(v.plane, m.spacing, tool_.pos));
      r << "tool_px " << plane_name(v.plane) << " " << q.x * sx << " " << q.y * sy << "\n";
      r << "tool_radius_px " << plane_name(v.plane) << " " << std::max(3.0f * sx, tool_.radius * cell) << "\n";
    }
  }
  std::ofstream f(path);
  f << r.str();
  if (!f) throw Error("cannot write report " + path);
}

}  // namespace hpcm::viewer
