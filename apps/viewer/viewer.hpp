#pragma once
// hpcm-viewer: GLFW window, Dear ImGui panel, three slice views of the deformed lattice,
// mouse grab tool, scripted (headless) playback with screenshots. The simulation runs on its
// own thread (SimRunner); this class is the display and never waits for a simulation frame.
#include <array>
#include <atomic>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "colour.hpp"
#include "hpcm/hpcm.hpp"
#include "options.hpp"
#include "png_io.hpp"
#include "sim_runner.hpp"
#include "view_geometry.hpp"

struct GLFWwindow;
struct ImDrawList;

namespace hpcm::viewer {

class SliceRenderer;
class Offscreen;

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
/// --stall-frame holds a simulation frame until the display has drawn this many frames.
inline constexpr int kStallDisplayFrames = 30;
/// The exact one-line message printed when there is no display.
inline constexpr const char* kNoDisplayMessage = "hpcm-viewer: no display (set DISPLAY or run under xvfb-run)";

class Viewer {
 public:
  Viewer(const Options& o, Session s);
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  /// Opens the window and runs (interactive loop, or scripted playback when --screenshot,
  /// --record or --bench-drag is given). Returns the exit code; throws hpcm::Error on failure.
  int run();

 private:
  enum class Layout { All = 0, Axial = 1, Coronal = 2, Sagittal = 3 };
  struct Rect {
    float x = 0, y = 0, w = 0, h = 0;
  };
  /// What a view's uploaded mesh was made from: a part is redone only when its inputs change.
  struct MeshInputs {
    bool valid = false;
    std::uint64_t model_id = 0;  ///< PublishedFrame::model_id
    std::uint64_t positions = 0;  ///< PublishedFrame::positions_id
    int slice = -1;
    Overlay seen_overlay = Overlay::None;
    bool seen_air = false;
    ColourSettings colours;
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
    MeshInputs mesh;
  };

  // the published frame on screen
  bool take_frame();  ///< takes the latest published frame; true when it is newer than the one shown
  void take_messages();
  void default_slices();
  void apply_params(bool force);
  void set_mode(DampingMode m);
  void set_running(bool r);

  // window and frame
  void open_window();
  void wait_for_display_slot();
  void draw(bool capture, Image* out);
  void update_layout();
  void update_meshes();
  void draw_slice_views(int fbw, int fbh, int ww, int wh);  ///< into scene_, when they changed
  void handle_input();
  void draw_panel();
  void panel_run_controls();
  void panel_backend();
  void panel_views();
  bool panel_solver_and_dynamics();  ///< true when a parameter changed
  bool panel_tissue_and_material();
  void panel_parameter_file();
  void panel_scenario();
  void panel_data();
  void draw_plots(float width, float height_each);
  void draw_plots_window();
  void draw_view_overlays();
  void draw_tool(ImDrawList* dl, const View& v);
  void fit_views();
  int view_at(Vec2f px) const;
  void handle_key(int key);
  static void key_callback(GLFWwindow* w, int key, int scancode, int action, int mods);
  void message(const std::string& m, bool error = false);
  void save_screenshot(const Image& img, const std::string& path);
  void write_report(const std::string& path, int image_w, int image_h) const;
  std::string rates_text() const;
  void settle();
  int run_script();
  int run_bench();
  int run_interactive();

  Options opt_;
  std::string title_;  ///< window title
  Params edit_;
  bool params_pending_ = false;
  std::string param_error_;
  bool cuda_ok_ = false;
  std::string cuda_why_;
  std::unique_ptr<SimRunner> runner_;
  std::shared_ptr<const PublishedFrame> shown_;  ///< the frame on screen
  bool running_ = true;                          ///< run / pause as last asked (the simulation follows)
  std::deque<FrameSample> hist_;
  std::uint64_t hist_epoch_ = 0;
  long sim_frames_seen_ = 0;  ///< frames stepped since start (every sample counted once)
  int frames_since_range_ = 0;  ///< simulation frames since the overlay range last followed them
  bool reset_overlay_range_ = false;
  bool slices_to_new_scenario_ = false;  ///< a scenario was asked for: its grab point sets the slices
  int hist_len_ = 300;
  bool log_speed_ = true;
  float sim_rate_ = 0;  ///< frames per second asked of the simulation, 0 = as fast as it can
  int max_fps_ = 60;
  RateMeter display_meter_{1.0}, sim_meter_{2.0};
  long display_count_ = 0;
  double last_draw_start_ = 0;
  int settle_frames_ = 0;  ///< frames still drawn after an event (ImGui settles widgets)
  std::atomic<long> stall_drawn_{-1};  ///< --stall-frame: display frames drawn while it was held
  std::string sim_error_;              ///< first error of the simulation thread (scripted runs stop on it)
  bool collect_samples_ = false;       ///< --bench-drag: keep every frame's sample
  std::vector<FrameSample> bench_samples_;
  /// --bench-drag: where a display frame's time goes (ms), to tell rendering from the rest.
  struct DrawTiming {
    double ui = 0;      ///< panel, plots and overlays built (Dear ImGui, CPU)
    double views = 0;   ///< slice meshes rebuilt, uploaded and drawn off-screen (only when changed)
    double gl = 0;      ///< views copied, panel and overlays drawn, buffers swapped (a software
                        ///< rasteriser such as Mesa's llvmpipe draws the pixels here)
  };
  std::vector<DrawTiming> bench_draws_;

  GLFWwindow* win_ = nullptr;
  bool glfw_ready_ = false, imgui_ready_ = false;
  std::unique_ptr<SliceRenderer> renderer_;
  std::unique_ptr<Offscreen> capture_;  ///< screenshots
  std::unique_ptr<Offscreen> scene_;    ///< the slice views, drawn again only when they change
  /// What the cached slice views were drawn from (besides the meshes, see scene_stale_).
  struct SceneKey {
    int fbw = 0, fbh = 0, ww = 0, wh = 0;
    bool wire = false;
    std::array<std::array<float, 7>, kPlaneCount> views{};  ///< x0, y0, w, h, zoom, pan; 0 when hidden
    bool operator==(const SceneKey&) const = default;
  };
  SceneKey scene_key_;
  bool scene_stale_ = true;  ///< a mesh was uploaded since the views were drawn
  long scene_draws_ = 0;     ///< times the slice views were drawn (the benchmark reports it)
  std::array<View, 3> views_{};
  Layout layout_ = Layout::All;
  Rect plots_rect_;
  bool plots_in_cell_ = true;
  bool hide_panel_ = false;
  float panel_w_ = 380;
  ColourSettings colour_;
  bool auto_overlay_ = true;
  bool wire_ = false;

  std::vector<int> key_queue_;  ///< key presses since the last display frame
  bool screenshot_request_ = false;
  int shot_counter_ = 0;
  int drag_view_ = -1, pan_view_ = -1;
  Vec2f drag_start_{};
  Vec3 drag_sent_{};  ///< the last tool offset sent for the drag

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
