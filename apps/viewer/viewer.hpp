#pragma once
// hpcm-viewer: GLFW window, Dear ImGui panel, three slice views of the deformed lattice,
// mouse grab tool, scripted (headless) playback with screenshots.
#include <array>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "colour.hpp"
#include "hpcm/hpcm.hpp"
#include "options.hpp"
#include "png_io.hpp"
#include "view_geometry.hpp"

struct GLFWwindow;

namespace hpcm::viewer {

class SliceRenderer;
class Capture;

/// What the viewer starts with, loaded and validated before the window opens.
struct Session {
  Model model;
  Params params;
  std::optional<Scenario> scenario;
  BackendKind backend = BackendKind::Cpu;
  std::string source;  ///< "phantom 96x96x64" or the input path
};

/// True when an X11 or Wayland display is named in the environment.
bool display_available();
/// The exact one-line message printed when there is no display.
inline constexpr const char* kNoDisplayMessage = "hpcm-viewer: no display (set DISPLAY or run under xvfb-run)";

class Viewer {
 public:
  Viewer(const Options& o, Session s);
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  /// Opens the window and runs (interactive loop, or scripted playback when --screenshot or
  /// --record is given). Returns the exit code; throws hpcm::Error on failure.
  int run();

 private:
  enum class Layout { All = 0, Axial = 1, Coronal = 2, Sagittal = 3 };
  struct Rect {
    float x = 0, y = 0, w = 0, h = 0;
  };
  struct View {
    Plane plane = Plane::Axial;
    int slice = 0;
    ViewTransform xf;
    Rect rect;
    bool visible = false;
    bool user_moved = false;  ///< zoomed or panned by the user (keep on resize)
    std::vector<Vec2f> verts;
    std::vector<Rgba> cols;
    float overlay_seen = 0;  ///< largest overlay value in the slice (automatic range)
  };
  struct Sample {
    int frame = 0;
    PerTissue speed{};
    float chainmail = 0, inertia = 0, snapshot = 0, total = 0;
  };
  struct Tool {
    bool held = false;   ///< the grab is held now
    bool shown = false;  ///< there has been a grab (drawn where it was released)
    Index centre = -1;
    Vec3 origin{};       ///< centre position at grab time
    Vec3 pos{};          ///< current (or last) tool position
    float radius = 1.5f;
  };

  // simulation
  void make_simulation(Model m, const Params& p, BackendKind k);
  void make_player();
  void step_once();
  void reset();
  void track_tool();
  void apply_params(bool force);
  void set_mode(DampingMode m);
  Index reference_centre() const;  ///< grab centre of the scenario (or paper centre), -1 if none
  void default_slices();

  // window and frame
  void open_window();
  void frame(int steps, bool capture, Image* out);
  void update_layout();
  void update_meshes();
  void handle_input();
  void draw_panel();
  void draw_plots(float width, float height_each);
  void draw_plots_window();
  void draw_view_overlays();
  void fit_views();
  int view_at(Vec2f px) const;
  void handle_key(int key);
  static void key_callback(GLFWwindow* w, int key, int scancode, int action, int mods);
  void message(const std::string& m, bool error = false);
  void save_screenshot(const Image& img, const std::string& path);
  void write_report(const std::string& path, int image_w, int image_h) const;
  int run_script();
  int run_interactive();

  Options opt_;
  std::string source_;
  Params edit_;
  bool params_pending_ = false;
  std::string param_error_;
  std::unique_ptr<Simulation> sim_;
  BackendKind backend_ = BackendKind::Cpu;
  bool cuda_ok_ = false;
  std::string cuda_why_;
  std::optional<Scenario> scenario_;
  std::unique_ptr<ScenarioPlayer> player_;
  bool scenario_active_ = false;
  std::vector<Vec3> prev_pos_;
  FrameReport last_{};
  std::deque<Sample> hist_;
  int hist_len_ = 300;
  bool log_speed_ = true;
  Tool tool_;

  GLFWwindow* win_ = nullptr;
  bool glfw_ready_ = false, imgui_ready_ = false;
  std::unique_ptr<SliceRenderer> renderer_;
  std::unique_ptr<Capture> capture_;
  std::array<View, 3> views_{};
  Layout layout_ = Layout::All;
  Rect plots_rect_;
  bool plots_in_cell_ = true;
  bool hide_panel_ = false;
  float panel_w_ = 380;
  ColourSettings colour_;
  bool auto_overlay_ = true;
  bool wire_ = false;

  bool running_ = true;
  std::vector<int> key_queue_;  ///< key presses since the last frame (none is lost in slow frames)
  int step_requests_ = 0;  ///< single frames asked for with n (each press one frame)
  bool screenshot_request_ = false;
  int steps_per_frame_ = 1;
  int shot_counter_ = 0;
  int drag_view_ = -1, pan_view_ = -1;
  Vec2f drag_start_{};
  Vec3 drag_offset0_{};

  // panel text fields
  char volume_path_[512] = {0};
  char params_path_[512] = "hpcm-params.toml";
  char scenario_path_[512] = {0};
  int load_downsample_ = 1;
  int phantom_dims_[3] = {96, 96, 64};
  int phantom_seed_ = 1;
  float phantom_noise_ = 12.0f;
  std::string message_;
  bool message_error_ = false;
};

}  // namespace hpcm::viewer
