// Scripted runs of hpcm-viewer: playback with screenshots or one PNG per frame, the drag
// benchmark, and the report of the view geometry. The display keeps drawing while it waits
// for the simulation thread, as in interactive use.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>

#include "gl.hpp"
#include "viewer.hpp"

namespace hpcm::viewer {
namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::lround(q * double(v.size() - 1)));
  return v[std::min(k, v.size() - 1)];
}

std::string omp_threads_text() {
  const char* t = std::getenv("OMP_NUM_THREADS");
  return t && *t ? std::string("OMP_NUM_THREADS=") + t : std::string("OMP_NUM_THREADS unset");
}

}  // namespace

// The end of a scripted run: a limited pull of a grab still held is said now, and the
// display catches up with the simulation's last word.
void Viewer::settle() {
  const std::uint64_t seq = runner_->latest_seq();
  runner_->announce_pending();
  while (runner_->latest_seq() == seq) {
    wait_for_display_slot();
    take_frame();
    draw(false, nullptr);
    if (glfwWindowShouldClose(win_)) throw Error("window closed during the scripted run");
  }
  take_frame();
}

int Viewer::run_script() {
  int frames = opt_.frames;
  if (frames < 0) frames = shown_->scenario.loaded ? shown_->scenario.frames : 0;
  if (opt_.stall_frame > frames)
    throw Error("--stall-frame " + std::to_string(opt_.stall_frame) + " is beyond the " + std::to_string(frames) +
                " frames played");
  hist_len_ = std::clamp(frames, 50, 2000);  // the plots span the whole scripted run
  // Two display frames before any simulation frame let ImGui settle its window sizes.
  draw(false, nullptr);
  draw(false, nullptr);
  auto check = [&] {
    if (!sim_error_.empty()) throw Error("simulation failed: " + sim_error_);
    if (glfwWindowShouldClose(win_)) throw Error("window closed during the scripted run");
  };
  Image img;
  if (!opt_.record.empty()) {
    // Lock-step: each simulation frame waits until the display has taken the previous one,
    // so every frame is drawn and written once.
    std::filesystem::create_directories(opt_.record);
    runner_->set_lockstep(true);
    runner_->run_to_frame(frames);
    int recorded = 0;
    char name[64];
    while (recorded < frames) {
      wait_for_display_slot();
      const bool fresh = take_frame();
      const bool capture = fresh && shown_->stepped && shown_->frame > recorded;
      draw(capture, capture ? &img : nullptr);
      if (capture) {
        std::snprintf(name, sizeof name, "frame_%05d.png", shown_->frame);
        save_screenshot(img, (std::filesystem::path(opt_.record) / name).string());
        recorded = shown_->frame;
      }
      check();
    }
  } else {
    runner_->run_to_frame(frames);
    while (shown_->frame < frames) {
      wait_for_display_slot();
      take_frame();
      draw(false, nullptr);
      check();
    }
  }
  settle();
  reset_overlay_range_ = true;  // the automatic overlay range of the last frame alone (reproducible)
  draw(false, nullptr);
  draw(true, &img);
  if (!opt_.screenshot.empty()) save_screenshot(img, opt_.screenshot);
  if (!opt_.report.empty()) write_report(opt_.report, img.width, img.height);
  std::printf("hpcm-viewer: played %d frames on %s (%lld elements, %s); the display drew %ld frames meanwhile%s%s\n",
              shown_->frame, shown_->source.c_str(), static_cast<long long>(shown_->model->size()),
              damping_mode_name(shown_->params.dynamics.mode), display_count_,
              opt_.screenshot.empty() ? "" : ", wrote ", opt_.screenshot.c_str());
  if (opt_.stall_frame > 0) {
    const long drawn = stall_drawn_.load();
    if (drawn < kStallDisplayFrames)
      throw Error("the display drew only " + std::to_string(drawn) + " frames while simulation frame " +
                  std::to_string(opt_.stall_frame) + " was held (expected " + std::to_string(kStallDisplayFrames) +
                  "): the display waited for the simulation");
    std::printf("hpcm-viewer: simulation frame %d was held until the display had drawn %ld more frames\n",
                opt_.stall_frame, drawn);
  }
  return 0;
}

// A drag like a mouse's on the axial view: the paper's grab point pulled anterior (-y) and
// back, 0 -> 6 -> 0 lattice units every 4 s, one tool move per display frame, while the
// simulation runs freely on its thread.
int Viewer::run_bench() {
  const double seconds = opt_.bench_drag;
  draw(false, nullptr);
  draw(false, nullptr);
  const Index centre = shown_->reference_centre;
  if (centre < 0)
    throw Error("--bench-drag: no grab point (the central axial line x = NX/2 meets no tissue with HU >= -500)");
  runner_->grab(centre, 0);
  runner_->set_running(true);
  collect_samples_ = true;
  bench_samples_.clear();
  bench_draws_.clear();
  const double t0 = glfwGetTime();
  const long display0 = display_count_;
  std::vector<double> frame_ms, frame_end, wait_ms;
  double last = t0;
  float max_requested = 0, max_shortfall = 0;
  long new_positions = 0;  // display frames that showed new tissue positions
  const long scene0 = scene_draws_;
  std::uint64_t positions_seen = shown_->positions_id;
  for (;;) {
    const double t = glfwGetTime() - t0;
    if (t >= seconds) break;
    const float pull = 6.0f * 0.5f * (1.0f - std::cos(float(2.0 * M_PI * t / 4.0)));
    runner_->move_tool({0, -pull, 0});
    const double before_wait = glfwGetTime();
    wait_for_display_slot();  // the frame cap (--max-fps) and window events; never a simulation frame
    wait_ms.push_back((glfwGetTime() - before_wait) * 1000.0);
    take_frame();
    if (shown_->positions_id != positions_seen) ++new_positions;
    positions_seen = shown_->positions_id;
    draw(false, nullptr);
    const ToolView& tool = shown_->tool;
    if (tool.held) {
      max_requested = std::max(max_requested, norm(tool.requested));
      max_shortfall = std::max(max_shortfall, norm(tool.requested - tool.achieved));
    }
    const double end = glfwGetTime();
    frame_ms.push_back((end - last) * 1000.0);
    frame_end.push_back(end - t0);
    last = end;
    if (!sim_error_.empty()) throw Error("simulation failed: " + sim_error_);
  }
  const double elapsed = glfwGetTime() - t0;
  // The figures cover the drag only, not the frames drawn (or stepped) while settling below.
  collect_samples_ = false;
  bench_draws_.resize(frame_ms.size());
  const long displayed = display_count_ - display0;
  const long scene_draws = scene_draws_ - scene0;
  runner_->release();
  runner_->set_running(false);
  settle();
  // Display frames per whole second of the run: the slowest one.
  long slowest = -1;
  for (int s = 0; s + 1 <= static_cast<int>(elapsed); ++s) {
    const long n = std::count_if(frame_end.begin(), frame_end.end(), [&](double e) { return e >= s && e < s + 1; });
    if (slowest < 0 || n < slowest) slowest = n;
  }
  std::vector<double> total, wall;
  for (const FrameSample& s : bench_samples_) {
    total.push_back(s.total);
    wall.push_back(s.wall);
  }
  const auto sims = static_cast<long>(bench_samples_.size());
  std::printf("hpcm-viewer: --bench-drag %.1f s on %s (%lld elements, %s, %s, %s)\n", elapsed, shown_->source.c_str(),
              static_cast<long long>(shown_->model->size()), damping_mode_name(shown_->params.dynamics.mode),
              backend_name(shown_->backend), omp_threads_text().c_str());
  std::printf("  display: %ld frames, %.1f fps (slowest whole second %ld frames; frame time median %.1f ms, "
              "95th percentile %.1f ms, max %.1f ms; limit %d fps)\n",
              displayed, double(displayed) / elapsed, slowest, percentile(frame_ms, 0.5), percentile(frame_ms, 0.95),
              frame_ms.empty() ? 0.0 : *std::max_element(frame_ms.begin(), frame_ms.end()), max_fps_);
  std::printf("  simulation: %ld frames, %.1f frames/s (SimTotal median %.1f ms, 95th percentile %.1f ms; wall per "
              "frame on its thread median %.1f ms, including the positions download)\n",
              sims, double(sims) / elapsed, percentile(total, 0.5), percentile(total, 0.95), percentile(wall, 0.5));
  std::vector<double> ui, views, gl;
  for (const DrawTiming& d : bench_draws_) {
    ui.push_back(d.ui);
    views.push_back(d.views);
    gl.push_back(d.gl);
  }
  bench_draws_.clear();
  const char* gl_renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  std::printf("  display frame time, median (95th percentile) ms: frame cap and events %.1f (%.1f), panel and "
              "overlays %.1f (%.1f), slice views %.1f (%.1f), copy, panel and swap %.1f (%.1f); OpenGL renderer: %s\n",
              percentile(wait_ms, 0.5), percentile(wait_ms, 0.95), percentile(ui, 0.5), percentile(ui, 0.95),
              percentile(views, 0.5), percentile(views, 0.95), percentile(gl, 0.5), percentile(gl, 0.95),
              gl_renderer ? gl_renderer : "unknown");
  std::printf("  display frames showing new tissue positions: %ld of %ld; slice views drawn in %ld of them (the "
              "others copied the views drawn last and redrew the tool, panel and HUD)\n",
              new_positions, displayed, scene_draws);
  std::printf("  tool: pulled up to %.2f lattice units; largest shortfall of a limited pull %.2f\n", double(max_requested),
              double(max_shortfall));
  Image img;
  if (!opt_.screenshot.empty() || !opt_.report.empty()) {
    draw(false, nullptr);
    draw(true, &img);
  }
  if (!opt_.screenshot.empty()) save_screenshot(img, opt_.screenshot);
  if (!opt_.report.empty()) write_report(opt_.report, img.width, img.height);
  return 0;
}

void Viewer::write_report(const std::string& path, int image_w, int image_h) const {
  const Model& m = *shown_->model;
  const ToolView& tool = shown_->tool;
  const ImGuiIO& io = ImGui::GetIO();
  const float sx = io.DisplaySize.x > 0 ? float(image_w) / io.DisplaySize.x : 1.0f;
  const float sy = io.DisplaySize.y > 0 ? float(image_h) / io.DisplaySize.y : 1.0f;
  std::ostringstream r;
  r << "# hpcm-viewer report: pixel coordinates are image pixels (x right, y down)\n";
  r << "image " << image_w << " " << image_h << "\n";
  r << "frames " << shown_->frame << "\n";
  r << "display_frames " << display_count_ << "\n";
  r << "dims " << m.dims.x << " " << m.dims.y << " " << m.dims.z << "\n";
  r << "elements " << m.size() << "\n";
  r << "mode " << damping_mode_name(shown_->params.dynamics.mode) << "\n";
  const Index g = tool.shown ? tool.centre : shown_->reference_centre;
  r << "grab_element " << g << "\n";
  if (tool.shown) {
    r << "tool_held " << (tool.held ? 1 : 0) << "\n";
    r << "tool_limited " << (tool.limited ? 1 : 0) << "\n";
    r << "tool_offset " << tool.achieved.x << " " << tool.achieved.y << " " << tool.achieved.z << "\n";
    r << "tool_requested " << tool.requested.x << " " << tool.requested.y << " " << tool.requested.z << "\n";
    r << "tool_offset_mm " << length_mm(tool.achieved, m.spacing) << " " << length_mm(tool.requested, m.spacing) << "\n";
  }
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
    if (tool.shown) {
      const Vec2f q = v.xf.to_pixel(to_display(v.plane, m.spacing, tool.pos()));
      r << "tool_px " << plane_name(v.plane) << " " << q.x * sx << " " << q.y * sy << "\n";
      r << "tool_radius_px " << plane_name(v.plane) << " " << std::max(3.0f * sx, tool.radius * cell) << "\n";
      const Vec2f w = v.xf.to_pixel(to_display(v.plane, m.spacing, tool.requested_pos()));
      r << "tool_requested_px " << plane_name(v.plane) << " " << w.x * sx << " " << w.y * sy << "\n";
    }
  }
  std::ofstream f(path);
  f << r.str();
  f.close();
  if (!f) throw Error("cannot write report " + path + " (disk full?)");
}

}  // namespace hpcm::viewer
