#include "viewer.hpp"

#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "gl.hpp"
#include "renderer.hpp"

namespace hpcm::viewer {
namespace {

std::string g_glfw_error;
void glfw_error(int code, const char* what) {
  g_glfw_error = std::string(what ? what : "unknown") + " (GLFW error " + std::to_string(code) + ")";
}

ImU32 im(Rgba c, int a = 255) { return IM_COL32(red(c), green(c), blue(c), a); }

const ImU32 kPlaneColour[3] = {IM_COL32(90, 160, 255, 200), IM_COL32(110, 220, 110, 200), IM_COL32(255, 170, 60, 200)};
const ImU32 kLimitColour = IM_COL32(255, 150, 40, 255);

}  // namespace

bool display_available() {
  const char* d = std::getenv("DISPLAY");
  const char* w = std::getenv("WAYLAND_DISPLAY");
  return (d && *d) || (w && *w);
}

// ------------------------------------------------------------------------------------------
// construction

Viewer::Viewer(const Options& o, Session s) : opt_(o), title_("hpcm-viewer - " + s.source), edit_(s.params) {
  layout_ = o.layout == "axial" ? Layout::Axial : o.layout == "coronal" ? Layout::Coronal
          : o.layout == "sagittal" ? Layout::Sagittal : Layout::All;
  hide_panel_ = o.hide_panel;
  wire_ = o.wire;
  running_ = !o.paused;
  sim_rate_ = static_cast<float>(o.sim_rate);
  max_fps_ = o.max_fps;
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
  // Explicit slice positions (validated against the lattice; applied once the window is open).
  const int dims[3] = {s.model.dims.x, s.model.dims.y, s.model.dims.z};
  const char* axis_name[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a)
    if (o.slices[a] >= dims[a])
      throw Error(std::string("--slices: ") + axis_name[a] + " = " + std::to_string(o.slices[a]) + " is outside [0, " +
                  std::to_string(dims[a] - 1) + "]");
  // The first simulation is made here, so that a backend or scenario error is reported before
  // any window opens; from start() on only the simulation thread touches it.
  auto sim = std::make_unique<Simulation>(std::move(s.model), s.params, s.backend);
  edit_ = sim->params();
  runner_ = std::make_unique<SimRunner>(std::move(sim), std::move(s.scenario), std::move(s.source));
}

Viewer::~Viewer() {
  runner_.reset();  // joins the simulation thread (it wakes the event loop through GLFW)
  renderer_.reset();
  capture_.reset();
  scene_.reset();
  if (imgui_ready_) {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
  if (win_) glfwDestroyWindow(win_);
  if (glfw_ready_) glfwTerminate();
}

// ------------------------------------------------------------------------------------------
// the published frame on screen, messages, commands

bool Viewer::take_frame() {
  std::shared_ptr<const PublishedFrame> f = runner_->latest();
  if (shown_ && f->seq == shown_->seq) return false;
  const std::shared_ptr<const PublishedFrame> old = std::move(shown_);
  shown_ = std::move(f);
  if (old && shown_->simulation != old->simulation) {  // new data: views start over
    fit_views();
    default_slices();
  }
  if (slices_to_new_scenario_ && old && shown_->epoch != old->epoch) {
    slices_to_new_scenario_ = false;
    default_slices();
  }
  if (old && shown_->running != old->running) running_ = shown_->running;  // e.g. a scenario was started
  if (shown_->stepped) frames_since_range_ += (old && old->epoch == shown_->epoch) ? std::max(1, shown_->frame - old->frame) : 1;
  return true;
}

void Viewer::take_messages() {
  for (const FrameSample& s : runner_->take_samples()) {
    if (s.epoch != hist_epoch_) {
      hist_.clear();
      hist_epoch_ = s.epoch;
    }
    hist_.push_back(s);
    ++sim_frames_seen_;
    if (collect_samples_) bench_samples_.push_back(s);
  }
  while (hist_.size() > 2000) hist_.pop_front();
  if (shown_ && shown_->epoch != hist_epoch_) {  // reset while paused: no sample says so
    hist_.clear();
    hist_epoch_ = shown_->epoch;
  }
  for (const Notice& n : runner_->take_notices()) {
    switch (n.kind) {
      case Notice::Kind::Info: message(n.text); break;
      case Notice::Kind::ParamError: param_error_ = n.text; break;
      case Notice::Kind::Error:
        message(n.text, true);
        if (sim_error_.empty()) sim_error_ = n.text;
        break;
      case Notice::Kind::PullLimited:  // once per grab, also on the terminal
        message(n.text);
        std::printf("hpcm-viewer: %s\n", n.text.c_str());
        std::fflush(stdout);
        break;
    }
  }
}

void Viewer::default_slices() {
  const Model& m = *shown_->model;
  Int3 c{m.dims.x / 2, m.dims.y / 2, m.dims.z / 2};
  if (shown_->reference_centre >= 0) c = m.coords(shown_->reference_centre);
  views_[static_cast<int>(Plane::Axial)].slice = c.z;
  // Coronal through the body centre: the paper pull is along y, so a coronal cut through the
  // grab point would show only out-of-plane motion.
  views_[static_cast<int>(Plane::Coronal)].slice = m.dims.y / 2;
  views_[static_cast<int>(Plane::Sagittal)].slice = c.x;
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
  runner_->set_params(edit_);  // applied between frames; a failure comes back as a notice
}

void Viewer::set_mode(DampingMode m) {
  edit_.dynamics.mode = m;
  apply_params(true);
  message(std::string("damping mode: ") + damping_mode_name(m));
}

void Viewer::set_running(bool r) {
  running_ = r;
  runner_->set_running(r);
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
  win_ = glfwCreateWindow(opt_.width, opt_.height, title_.c_str(), nullptr, nullptr);
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
  // Our key callback first: ImGui's backend chains to it. Presses are queued and handled in
  // the next display frame.
  glfwSetWindowUserPointer(win_, this);
  glfwSetKeyCallback(win_, key_callback);
  ImGui_ImplGlfw_InitForOpenGL(win_, true);
  ImGui_ImplOpenGL3_Init("#version 330 core");
  imgui_ready_ = true;

  renderer_ = std::make_unique<SliceRenderer>();
  renderer_->init();
  capture_ = std::make_unique<Offscreen>("the screenshot");
  scene_ = std::make_unique<Offscreen>("the slice views");
}

int Viewer::run() {
  open_window();
  // Each published frame wakes the event loop (glfwPostEmptyEvent may be called from any thread).
  runner_->set_wake([] { glfwPostEmptyEvent(); });
  runner_->set_rate(sim_rate_);
  if (opt_.stall_frame > 0)
    runner_->set_before_step([this](int k) {
      if (k == opt_.stall_frame) stall_drawn_ = runner_->wait_for_display_frames(kStallDisplayFrames, 120.0);
    });
  runner_->start(opt_.scripted() ? false : running_);
  take_frame();
  default_slices();
  const Plane by_axis[3] = {Plane::Sagittal, Plane::Coronal, Plane::Axial};
  for (int a = 0; a < 3; ++a)
    if (opt_.slices[a] >= 0) views_[static_cast<int>(by_axis[a])].slice = opt_.slices[a];
  if (opt_.bench()) return run_bench();
  return opt_.scripted() ? run_script() : run_interactive();
}

int Viewer::run_interactive() {
  while (!glfwWindowShouldClose(win_)) {
    wait_for_display_slot();
    take_frame();
    const bool cap = screenshot_request_;
    screenshot_request_ = false;
    Image img;
    draw(cap, cap ? &img : nullptr);
    if (cap) {
      char name[96];
      std::snprintf(name, sizeof name, "hpcm-viewer-%05d-%02d.png", shown_->frame, shot_counter_++);
      try {
        save_screenshot(img, name);
      } catch (const Error& e) {
        message(e.what(), true);
      }
    }
  }
  return 0;
}

void Viewer::wait_for_display_slot() {
  // At most max_fps display frames per second: the rest of the slot is left to the simulation.
  if (max_fps_ > 0) {
    const double next = last_draw_start_ + 1.0 / max_fps_;
    const double now = glfwGetTime();
    if (now < next) std::this_thread::sleep_for(std::chrono::duration<double>(next - now));
  }
  if (opt_.scripted()) {
    glfwPollEvents();
    return;
  }
  // Nothing new to show and nobody interacting: sleep until an event (input, or the
  // simulation thread's wake-up when it publishes a frame).
  const bool busy = runner_->latest_seq() != shown_->seq || drag_view_ >= 0 || pan_view_ >= 0 || screenshot_request_ ||
                    ImGui::IsAnyItemActive() || settle_frames_ > 0;
  if (busy) {
    glfwPollEvents();
    if (settle_frames_ > 0) --settle_frames_;
  } else {
    glfwWaitEventsTimeout(0.5);
    settle_frames_ = 2;  // ImGui needs a frame or two to finish reacting to the event
  }
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
// one display frame

void Viewer::draw(bool capture, Image* out) {
  last_draw_start_ = glfwGetTime();
  take_messages();
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  update_layout();
  if (!opt_.scripted()) handle_input();
  if (!hide_panel_) draw_panel();
  // Threshold and material edits rebuild the materials: apply them once the widget is released.
  if (params_pending_ && !(materials_differ(edit_, shown_->params) && ImGui::IsAnyItemActive())) apply_params(false);
  if (plots_in_cell_) draw_plots_window();
  draw_view_overlays();
  ImGui::Render();
  const double t_ui = glfwGetTime();

  int fbw = 0, fbh = 0, ww = 0, wh = 0;
  glfwGetFramebufferSize(win_, &fbw, &fbh);
  glfwGetWindowSize(win_, &ww, &wh);
  update_meshes();
  const bool drawable = fbw > 0 && fbh > 0;  // not while the window is minimised
  if (drawable) draw_slice_views(fbw, fbh, ww, wh);
  const double t_views = glfwGetTime();
  // The frame: the slice views as drawn last, the panel, tool and HUD on top.
  if (capture) capture_->bind(fbw, fbh);
  if (drawable) scene_->blit_to(capture ? capture_->id() : 0);
  glViewport(0, 0, fbw, fbh);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  if (capture) {
    if (out) *out = capture_->read();
    capture_->blit_to(0);  // the window shows what was captured
  }
  glfwSwapBuffers(win_);
  if (collect_samples_)
    bench_draws_.push_back({(t_ui - last_draw_start_) * 1e3, (t_views - t_ui) * 1e3, (glfwGetTime() - t_views) * 1e3});
  ++display_count_;
  const double now = glfwGetTime();
  display_meter_.add(now, display_count_);
  sim_meter_.add(now, sim_frames_seen_);
  runner_->note_display_frame();
}

// Software rasterisers (Mesa's llvmpipe) spend most of a frame on the slice meshes' triangles;
// while only the tool, the panel or the HUD change, the views drawn last are copied instead.
void Viewer::draw_slice_views(int fbw, int fbh, int ww, int wh) {
  SceneKey key;
  key.fbw = fbw;
  key.fbh = fbh;
  key.ww = ww;
  key.wh = wh;
  key.wire = wire_;
  for (int p = 0; p < kPlaneCount; ++p) {
    const View& v = views_[p];
    if (v.visible) key.views[p] = {v.xf.x0, v.xf.y0, v.xf.w, v.xf.h, v.xf.zoom, v.xf.pan.x, v.xf.pan.y};
  }
  if (!scene_stale_ && key == scene_key_) return;
  scene_->bind(fbw, fbh);
  const float sx = ww > 0 ? float(fbw) / float(ww) : 1.0f, sy = wh > 0 ? float(fbh) / float(wh) : 1.0f;
  glViewport(0, 0, fbw, fbh);
  glClearColor(0.06f, 0.065f, 0.08f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  for (int p = 0; p < kPlaneCount; ++p)
    if (views_[p].visible) renderer_->draw(p, views_[p].xf, sx, sy, float(wh), wire_);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  scene_key_ = key;
  scene_stale_ = false;
  ++scene_draws_;
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
        v.xf = fit_view(*shown_->model, p, r.x, r.y, r.w, r.h);
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
    v.xf = fit_view(*shown_->model, v.plane, v.rect.x, v.rect.y, v.rect.w, v.rect.h);
  }
}

// Only what changed is redone: vertex positions when a new frame or another slice is shown,
// colours when those or the colour settings changed (or, with an overlay, the positions).
void Viewer::update_meshes() {
  const Model& m = *shown_->model;
  const std::vector<Vec3>& disp = *shown_->disp;
  static const std::vector<Vec3> kNoPrev;
  const std::vector<Vec3>& prev = shown_->prev ? *shown_->prev : kNoPrev;
  bool moved[kPlaneCount] = {false, false, false};
  bool seen_changed = false;
  float seen = 0;
  for (int p = 0; p < kPlaneCount; ++p) {
    View& v = views_[p];
    if (!v.visible) continue;
    v.slice = std::clamp(v.slice, 0, slice_count(m, v.plane) - 1);
    MeshInputs& in = v.mesh;
    moved[p] = !in.valid || in.model_id != shown_->model_id || in.slice != v.slice || in.positions != shown_->positions_id;
    if (moved[p]) {
      slice_positions(m, v.plane, v.slice, disp, v.verts);
      const auto sz = slice_size(m, v.plane);
      renderer_->upload_positions(p, sz[0], sz[1], v.verts);
      scene_stale_ = true;
    }
    if (moved[p] || in.seen_overlay != colour_.overlay || in.seen_air != colour_.overlay_air) {
      v.overlay_seen = slice_overlay_max(m, v.plane, v.slice, disp, prev, colour_.overlay, colour_.overlay_air);
      seen_changed = true;
    }
    seen = std::max(seen, v.overlay_seen);
  }
  if (auto_overlay_ && colour_.overlay != Overlay::None && (seen_changed || reset_overlay_range_)) {
    // Automatic range: follows the largest value shown and decays slowly (per simulation
    // frame, not per display frame) so the scale is stable.
    const float floor_v = colour_.overlay == Overlay::Speed ? 1e-3f : 1e-2f;
    const float decayed = reset_overlay_range_ ? 0.0f : colour_.overlay_max * std::pow(0.98f, float(std::max(1, frames_since_range_)));
    colour_.overlay_max = std::max({seen, decayed, floor_v});
    frames_since_range_ = 0;
    reset_overlay_range_ = false;
  }
  for (int p = 0; p < kPlaneCount; ++p) {
    View& v = views_[p];
    if (!v.visible) continue;
    MeshInputs& in = v.mesh;
    const bool geometry = !in.valid || in.model_id != shown_->model_id || in.slice != v.slice;
    if (geometry || (moved[p] && colour_.overlay != Overlay::None) || !(in.colours == colour_)) {
      slice_colours(m, v.plane, v.slice, disp, prev, colour_, v.cols);
      renderer_->upload_colours(p, v.cols);
      scene_stale_ = true;
    }
    in = {true, shown_->model_id, shown_->positions_id, v.slice, colour_.overlay, colour_.overlay_air, colour_};
  }
}

int Viewer::view_at(Vec2f px) const {
  for (int p = 0; p < kPlaneCount; ++p)
    if (views_[p].visible && views_[p].xf.contains(px)) return p;
  return -1;
}

// ------------------------------------------------------------------------------------------
// input: everything that touches the simulation goes to its thread as a command

void Viewer::handle_input() {
  ImGuiIO& io = ImGui::GetIO();
  const Vec2f mp{io.MousePos.x, io.MousePos.y};
  const Model& m = *shown_->model;
  if (!io.WantCaptureMouse) {
    const int v = view_at(mp);
    if (v >= 0 && ImGui::IsMouseClicked(0) && drag_view_ < 0) {
      View& view = views_[v];
      const Vec2f d = view.xf.to_display(mp);
      const PlaneAxes ax = plane_axes(view.plane);
      const float cell = float(std::max(m.spacing[ax.u], m.spacing[ax.v]));
      // The mesh on screen is the one picked from: what you see is what you grab.
      const Index e = pick_element(m, view.plane, view.slice, view.verts, d, 1.0f * cell);
      if (e >= 0) {
        runner_->grab(e, edit_.solver.grab_radius);
        drag_view_ = v;
        drag_start_ = d;
        drag_sent_ = {};
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
      if (!(off == drag_sent_)) runner_->move_tool(off);
      drag_sent_ = off;
    } else {
      runner_->release();  // the tissue's residual motion plays out
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
    case GLFW_KEY_SPACE: set_running(!running_); break;
    case GLFW_KEY_N:
      running_ = false;
      runner_->step_frames(1);
      break;
    case GLFW_KEY_R:
      runner_->reset();
      drag_view_ = -1;
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
// drawing on the views (tool, labels, rates, slice lines, colour bar)

std::string Viewer::rates_text() const {
  double wall = 0, total = 0;
  const int n = std::min<int>(static_cast<int>(hist_.size()), 30);
  for (int k = 0; k < n; ++k) {
    const FrameSample& s = hist_[hist_.size() - 1 - static_cast<std::size_t>(k)];
    wall += s.wall;
    total += s.total;
  }
  char buf[160];
  if (n > 0)
    std::snprintf(buf, sizeof buf, "display %.0f fps | sim %.1f fps, %.1f ms/frame (SimTotal %.1f)",
                  display_meter_.rate(), sim_meter_.rate(), wall / n, total / n);
  else
    std::snprintf(buf, sizeof buf, "display %.0f fps | sim: no frame yet", display_meter_.rate());
  return buf;
}

void Viewer::draw_tool(ImDrawList* dl, const View& v) {
  const ToolView& tool = shown_->tool;
  const Model& m = *shown_->model;
  const PlaneAxes ax = plane_axes(v.plane);
  const float sp = 0.5f * float(m.spacing[ax.u] + m.spacing[ax.v]);
  const float rpx = std::max(3.0f, tool.radius * sp * v.xf.zoom);
  // The tool is drawn where the tissue is (the achieved offset); a limited pull also marks
  // where the input asked for.
  const Vec3 pos = tool.pos();
  const Vec2f c = v.xf.to_pixel(to_display(v.plane, m.spacing, pos));
  const Vec2f o = v.xf.to_pixel(to_display(v.plane, m.spacing, tool.origin));
  const bool in_plane = std::fabs(pos[ax.n] - float(v.slice)) <= tool.radius + 0.5f;
  const int a = in_plane ? 255 : 110;
  if (!tool.held) {
    dl->AddCircle(ImVec2(c.x, c.y), rpx, IM_COL32(255, 255, 255, a * 3 / 4), 32, 1.5f);
    dl->AddCircle(ImVec2(c.x, c.y), rpx + 3, IM_COL32(0, 0, 0, a / 2), 32, 1.0f);
    dl->AddText(ImVec2(c.x + rpx + 4, c.y - 7), IM_COL32(230, 230, 230, a), "released");
    return;
  }
  dl->AddLine(ImVec2(o.x, o.y), ImVec2(c.x, c.y), IM_COL32(0, 230, 255, a), 2.0f);
  dl->AddCircleFilled(ImVec2(o.x, o.y), 2.5f, IM_COL32(0, 230, 255, a));
  dl->AddCircleFilled(ImVec2(c.x, c.y), rpx, IM_COL32(0, 230, 255, a / 4), 32);
  dl->AddCircle(ImVec2(c.x, c.y), rpx, IM_COL32(0, 240, 255, a), 32, 2.5f);
  dl->AddLine(ImVec2(c.x - rpx - 6, c.y), ImVec2(c.x + rpx + 6, c.y), IM_COL32(0, 240, 255, a), 1.5f);
  dl->AddLine(ImVec2(c.x, c.y - rpx - 6), ImVec2(c.x, c.y + rpx + 6), IM_COL32(0, 240, 255, a), 1.5f);
  const Vec2f q = v.xf.to_pixel(to_display(v.plane, m.spacing, tool.requested_pos()));
  if (tool.limited && std::hypot(q.x - c.x, q.y - c.y) > 2.0f) {  // not where the view shows no difference
    const float k = 6;
    dl->AddLine(ImVec2(c.x, c.y), ImVec2(q.x, q.y), kLimitColour, 1.0f);
    dl->AddLine(ImVec2(q.x - k, q.y - k), ImVec2(q.x + k, q.y + k), kLimitColour, 2.0f);
    dl->AddLine(ImVec2(q.x - k, q.y + k), ImVec2(q.x + k, q.y - k), kLimitColour, 2.0f);
    dl->AddText(ImVec2(q.x + k + 3, q.y - 7), kLimitColour, "requested");
  }
}

void Viewer::draw_view_overlays() {
  ImDrawList* dl = ImGui::GetBackgroundDrawList();
  const Model& m = *shown_->model;
  const ImGuiIO& io = ImGui::GetIO();
  bool bar_drawn = false, hud_drawn = false;
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
    if (shown_->tool.shown && !opt_.hide_tool) draw_tool(dl, v);
    // Radius preview under the cursor.
    if (!opt_.scripted() && drag_view_ < 0 && !io.WantCaptureMouse && v.xf.contains({io.MousePos.x, io.MousePos.y})) {
      const float sp = 0.5f * float(m.spacing[ax.u] + m.spacing[ax.v]);
      dl->AddCircle(io.MousePos, std::max(3.0f, edit_.solver.grab_radius * sp * v.xf.zoom), IM_COL32(0, 230, 255, 120), 32,
                    1.0f);
    }
    // Labels.
    char buf[160];
    const int count = slice_count(m, v.plane);
    std::snprintf(buf, sizeof buf, "%s  %c = %d / %d", plane_name(v.plane), "xyz"[ax.n], v.slice, count - 1);
    dl->AddText(ImVec2(r0.x + 6, r0.y + 4), kPlaneColour[p] | IM_COL32(0, 0, 0, 255), buf);
    static const char* letters[3][4] = {{"R", "L", "A", "P"}, {"R", "L", "S", "I"}, {"A", "P", "S", "I"}};
    const ImU32 lc = IM_COL32(200, 200, 200, 200);
    dl->AddText(ImVec2(r0.x + 6, 0.5f * (r0.y + r1.y) - 7), lc, letters[p][0]);
    dl->AddText(ImVec2(r1.x - 14, 0.5f * (r0.y + r1.y) - 7), lc, letters[p][1]);
    dl->AddText(ImVec2(0.5f * (r0.x + r1.x) - 4, r0.y + 20), lc, letters[p][2]);
    dl->AddText(ImVec2(0.5f * (r0.x + r1.x) - 4, r1.y - 18), lc, letters[p][3]);
    // The HUD: frame, both rates, and a limited pull (live figures).
    if (!hud_drawn && (p == static_cast<int>(Plane::Axial) || layout_ != Layout::All)) {
      hud_drawn = true;
      const DampingMode dm = shown_->params.dynamics.mode;
      std::snprintf(buf, sizeof buf, "frame %d  %c  %s%s", shown_->frame,
                    dm == DampingMode::None ? 'A' : dm == DampingMode::Simple ? 'B' : 'C',
                    shown_->report.deform ? "deform" : "idle", shown_->running ? "" : "  (paused)");
      dl->AddText(ImVec2(r0.x + 6, r0.y + 20), IM_COL32(220, 220, 220, 230), buf);
      dl->AddText(ImVec2(r0.x + 6, r0.y + 36), IM_COL32(220, 220, 220, 230), rates_text().c_str());
      const ToolView& t = shown_->tool;
      if (t.held && t.limited) {
        std::snprintf(buf, sizeof buf, "pull limited: %.2f of the requested %.2f lattice units, %.2f (%.1f mm) short",
                      double(norm(t.achieved)), double(norm(t.requested)), double(norm(t.requested - t.achieved)),
                      length_mm(t.requested - t.achieved, m.spacing));
        dl->AddText(ImVec2(r0.x + 6, r0.y + 52), kLimitColour, buf);
      }
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

}  // namespace hpcm::viewer
