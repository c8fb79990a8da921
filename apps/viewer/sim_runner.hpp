#pragma once
// The simulation thread of hpcm-viewer. It owns the Simulation (and the scenario player),
// steps frames on its own thread and publishes each finished frame as an immutable snapshot;
// the display takes the latest snapshot whenever it redraws and never waits for a frame.
// Input, parameters, resets and new data reach the simulation as commands, applied in order
// between frames. GL-free (unit-tested in tests/viewer/test_sim_runner.cpp).
//
// Buffers: the positions of a frame are downloaded once into a buffer from a small pool and
// shared by pointer: one is being written by the simulation, one is the latest published
// frame, one (or two, with the previous frame for the speed overlay) is being drawn. A buffer
// goes back to the pool when nobody holds it, so no frame is copied twice.
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "hpcm/hpcm.hpp"

namespace hpcm::viewer {

/// The grab tool as the display draws it.
struct ToolView {
  bool held = false;   ///< a grab is held now
  bool shown = false;  ///< there has been a grab since the last reset (drawn where it was released)
  Index centre = -1;
  Vec3 origin{};       ///< the centre element's position when it was grabbed
  Vec3 achieved{};     ///< tool offset the tissue followed (lattice units)
  Vec3 requested{};    ///< tool offset the input asked for
  float radius = 0;
  bool limited = false;  ///< the pull was limited: achieved != requested

  Vec3 pos() const { return origin + achieved; }
  Vec3 requested_pos() const { return origin + requested; }
};

/// The scenario as the panel shows it.
struct ScenarioView {
  bool loaded = false;
  std::string name;
  int frames = 0;
  std::size_t grabs = 0;
  bool playing = false;  ///< the player drives the tool (false once the mouse took over)
  bool done = false;
  int player_frame = 0;
};

/// One finished simulation frame (or the state after a command), immutable once published.
struct PublishedFrame {
  std::uint64_t seq = 0;    ///< publish counter
  std::uint64_t epoch = 0;  ///< changes on reset and on a new simulation (history starts again)
  std::uint64_t simulation = 0;  ///< changes when a new simulation replaces the old one (new data)
  int frame = 0;            ///< simulation frame counter (frames stepped since the last reset)
  bool stepped = false;     ///< published after a step (not after a command only)
  bool running = false;     ///< the simulation runs frames on its own (not paused)
  std::shared_ptr<const Model> model;             ///< shared copy, replaced when materials are rebuilt
  std::uint64_t model_id = 0;                     ///< changes with `model`
  std::shared_ptr<const std::vector<Vec3>> disp;  ///< u(t) = X(t) - X0, frame-end displacements
  std::uint64_t positions_id = 0;                 ///< changes when `disp` is a new download
  std::shared_ptr<const std::vector<Vec3>> prev;  ///< u(t-1); null after a reset (speed 0)
  FrameReport report{};                           ///< of the last step (default after a reset)
  Params params;
  BackendKind backend = BackendKind::Cpu;
  std::string source;       ///< what is simulated ("phantom 96x96x64 (seed 1)", a file name)
  ToolView tool;
  ScenarioView scenario;
  Index reference_centre = -1;  ///< the scenario's (or the paper's) grab centre, -1 if none
};

/// Per-frame figures for the plots; every stepped frame yields one, none is skipped.
struct FrameSample {
  std::uint64_t epoch = 0;
  int frame = 0;
  PerTissue speed{};
  float chainmail = 0, inertia = 0, snapshot = 0, total = 0;  ///< library stage times (ms)
  float wall = 0;  ///< ms the simulation thread spent on the frame (step, download, publish)
};

/// A message for the user from the simulation thread.
struct Notice {
  enum class Kind { Info, Error, ParamError, PullLimited };
  Kind kind = Kind::Info;
  std::string text;
};

/// Length in millimetres of an offset in lattice units (per-axis voxel spacing).
double length_mm(Vec3 offset, const std::array<double, 3>& spacing);

/// The pull achieved, for the panel: "offset (0.00, -6.00, 0.00) = 6.00 lattice units (37.50 mm)".
std::string tool_offset_text(Vec3 achieved, const std::array<double, 3>& spacing);

/// "pull limited: the tool moved 4.21 of the requested 6.00 lattice units (12.63 of 18.00 mm),
/// 1.79 lattice units (5.37 mm) short: ...; achieved offset (...), requested (...)".
std::string limited_pull_text(Vec3 achieved, Vec3 requested, const std::array<double, 3>& spacing);

class SimRunner {
 public:
  /// Takes a constructed simulation (the first one is made by the caller, so that errors
  /// surface before any window opens). Nothing runs before start().
  SimRunner(std::unique_ptr<Simulation> sim, std::optional<Scenario> scenario, std::string source);
  ~SimRunner();  ///< stops the thread
  SimRunner(const SimRunner&) = delete;
  SimRunner& operator=(const SimRunner&) = delete;

  /// Publishes the initial state and starts the simulation thread (paused unless `running`).
  void start(bool running);
  /// Stops the thread after the frame in progress. The simulation is kept.
  void stop();

  // --- commands: any thread; applied on the simulation thread between frames, in order ---
  void grab(Index centre, float radius);  ///< stops a playing scenario (the mouse takes over)
  void move_tool(Vec3 offset);            ///< consecutive moves collapse into the last one
  void release();
  void set_running(bool running);
  void step_frames(int n);       ///< n more frames, then pause
  void run_to_frame(int frame);  ///< step until the frame counter reaches `frame`, then pause
  void reset();                  ///< back to rest; the scenario (if any) starts again
  void set_params(const Params& p);
  void set_scenario(std::optional<Scenario> s);  ///< reset and play it (or none)
  /// A new simulation on this model (loaded volume, generated phantom, other backend).
  /// `done` is posted as a notice once it runs.
  void replace(std::shared_ptr<Model> model, const Params& p, BackendKind backend, std::string source,
               std::string done);
  void set_rate(double frames_per_second);  ///< 0: as fast as possible
  /// Says now that the pull of the grab still held was limited, if it was and that was not
  /// said yet (a limited pull is otherwise announced when its grab ends, with its largest
  /// shortfall). For the end of a scripted run.
  void announce_pending();
  /// Lock-step (recording): the next frame waits until the display has taken the last one.
  void set_lockstep(bool on);

  // --- display side: none of these waits for a simulation frame ---
  /// The latest published frame (marks it taken, for lock-step).
  std::shared_ptr<const PublishedFrame> latest();
  /// Publish counter of the latest frame (a newer frame than the one drawn is waiting).
  std::uint64_t latest_seq() const;
  std::vector<FrameSample> take_samples();
  std::vector<Notice> take_notices();
  /// Called by the display after each drawn frame (counted for reports and the stall aid).
  void note_display_frame();
  long display_frames() const { return display_frames_.load(); }

  /// Called on the simulation thread after each publish (the viewer wakes its event loop).
  void set_wake(std::function<void()> wake);
  /// Test aid: called on the simulation thread just before frame `frame_number` is stepped
  /// (the frame counter goes from frame_number - 1 to frame_number); it may block.
  void set_before_step(std::function<void(int frame_number)> hook);
  /// Blocks the calling thread until the display has drawn `count` more frames, or
  /// `timeout_s` passed. Returns the display frames drawn meanwhile.
  long wait_for_display_frames(long count, double timeout_s);

 private:
  struct Command {
    bool is_move = false;
    std::function<void()> apply;
  };
  void post(Command c);
  void loop();
  bool wants_step() const;  // simulation thread only
  void step_frame();
  void publish(bool stepped);
  void make_player();
  /// After a reset, new data or a new scenario: no tool, no report, positions downloaded again,
  /// a new epoch for the display.
  void start_over();
  void rebuild_model_copy();
  void track_tool();
  void announce_limited_pull();
  Index reference_centre() const;
  /// A positions buffer and the stamp of its content (Backend::download_displacements_since):
  /// a buffer taken again is brought up to date from the bricks written since.
  struct PooledBuffer {
    std::shared_ptr<std::vector<Vec3>> data;
    std::uint64_t since = 0;
  };
  PooledBuffer& acquire_buffer();
  void notice(Notice::Kind k, std::string text);

  // Owned by the simulation thread once started.
  std::unique_ptr<Simulation> sim_;
  std::optional<Scenario> scenario_;
  std::unique_ptr<ScenarioPlayer> player_;
  bool scenario_playing_ = false;
  std::string source_;
  std::shared_ptr<const Model> model_copy_;
  std::uint64_t model_id_ = 0;
  std::vector<PooledBuffer> pool_;
  std::shared_ptr<const std::vector<Vec3>> last_disp_, last_prev_;
  bool positions_dirty_ = true;  // positions may differ from last_pos_ (a step, reset, new data)
  std::uint64_t positions_id_ = 0;
  FrameReport last_report_{};
  ToolView tool_;
  struct LimitedPull {
    bool seen = false;       // the pull of this grab was limited at some point
    bool announced = false;  // and the user was told
    float shortfall = 0;     // the largest |requested - achieved| so far, with its offsets:
    Vec3 achieved{}, requested{};
  } limit_;
  std::uint64_t epoch_ = 1, simulation_ = 1, seq_ = 0;
  bool running_ = false;
  int budget_ = 0;         // single frames asked for
  int target_frame_ = -1;  // run_to_frame
  double rate_ = 0;
  bool lockstep_ = false;
  std::function<void()> wake_;
  std::function<void(int)> before_step_;

  // Shared, under mu_.
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Command> commands_;
  bool quit_ = false;
  std::shared_ptr<const PublishedFrame> latest_;
  std::uint64_t taken_seq_ = 0;
  std::vector<FrameSample> samples_;
  std::vector<Notice> notices_;

  std::atomic<long> display_frames_{0};
  std::mutex display_mu_;
  std::condition_variable display_cv_;
  std::thread thread_;
};

/// Frames per second over a sliding window of about `window_s` seconds (display or
/// simulation rate for the HUD). Feed it (time in seconds, running frame count).
class RateMeter {
 public:
  explicit RateMeter(double window_s = 1.0) : window_(window_s) {}
  void add(double t, long count);
  double rate() const;  ///< 0 until two samples span some time
  void clear() { pts_.clear(); }

 private:
  double window_;
  std::deque<std::pair<double, long>> pts_;
};

}  // namespace hpcm::viewer
