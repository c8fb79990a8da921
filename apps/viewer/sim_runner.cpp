#include "sim_runner.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

namespace hpcm::viewer {

using Clock = std::chrono::steady_clock;

double length_mm(Vec3 offset, const std::array<double, 3>& spacing) {
  double s = 0;
  for (int a = 0; a < 3; ++a) s += double(offset[a]) * spacing[a] * double(offset[a]) * spacing[a];
  return std::sqrt(s);
}

std::string tool_offset_text(Vec3 achieved, const std::array<double, 3>& spacing) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "offset (%.2f, %.2f, %.2f) = %.2f lattice units (%.2f mm)", double(achieved.x),
                double(achieved.y), double(achieved.z), double(norm(achieved)), length_mm(achieved, spacing));
  return buf;
}

std::string limited_pull_text(Vec3 achieved, Vec3 requested, const std::array<double, 3>& spacing) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "pull limited: the tool moved %.2f of the requested %.2f lattice units (%.2f of %.2f mm), %.2f lattice "
                "units (%.2f mm) short: the tissue between the tool and what holds it (anchored bone, the lattice "
                "border) cannot stretch further; achieved offset (%.2f, %.2f, %.2f), requested (%.2f, %.2f, %.2f)",
                double(norm(achieved)), double(norm(requested)), length_mm(achieved, spacing),
                length_mm(requested, spacing), double(norm(requested - achieved)),
                length_mm(requested - achieved, spacing), double(achieved.x), double(achieved.y), double(achieved.z),
                double(requested.x), double(requested.y), double(requested.z));
  return buf;
}

// ------------------------------------------------------------------------------------------

SimRunner::SimRunner(std::unique_ptr<Simulation> sim, std::optional<Scenario> scenario, std::string source)
    : sim_(std::move(sim)), scenario_(std::move(scenario)), source_(std::move(source)) {
  rebuild_model_copy();
  make_player();
}

SimRunner::~SimRunner() { stop(); }

void SimRunner::start(bool running) {
  if (thread_.joinable()) return;
  running_ = running;
  track_tool();
  publish(false);  // the display has a frame before the thread runs
  {
    std::lock_guard lk(mu_);
    quit_ = false;
  }
  thread_ = std::thread([this] { loop(); });
}

void SimRunner::stop() {
  {
    std::lock_guard lk(mu_);
    quit_ = true;
  }
  cv_.notify_all();
  {
    std::lock_guard lk(display_mu_);
  }
  display_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void SimRunner::post(Command c) {
  {
    std::lock_guard lk(mu_);
    // A move replaces a move still waiting: only the last offset matters before a frame.
    if (c.is_move && !commands_.empty() && commands_.back().is_move) commands_.back() = std::move(c);
    else commands_.push_back(std::move(c));
  }
  cv_.notify_all();
}

void SimRunner::notice(Notice::Kind k, std::string text) {
  std::lock_guard lk(mu_);
  notices_.push_back({k, std::move(text)});
}

// ------------------------------------------------------------------------------------------
// commands

void SimRunner::grab(Index centre, float radius) {
  post({false, [this, centre, radius] {
          announce_limited_pull();  // of the grab before, if it was never released
          sim_->grab(centre, radius);
          if (scenario_playing_) notice(Notice::Kind::Info, "scenario stopped: the mouse took over the tool");
          scenario_playing_ = false;
          tool_ = {};
          tool_.centre = centre;
          tool_.held = tool_.shown = true;
          tool_.origin = sim_->model().rest(centre) + sim_->displacement(centre);
          tool_.radius = radius > 0 ? radius : sim_->params().solver.grab_radius;
          limit_ = {};
        }});
}

void SimRunner::move_tool(Vec3 offset) {
  post({true, [this, offset] {
          if (sim_->grabbing()) sim_->move_tool(offset);
        }});
}

void SimRunner::release() {
  post({false, [this] {
          sim_->release();  // the tissue's residual motion plays out
          tool_.held = false;
        }});
}

void SimRunner::set_running(bool running) {
  post({false, [this, running] {
          running_ = running;
          budget_ = 0;
          target_frame_ = -1;
        }});
}

void SimRunner::step_frames(int n) {
  post({false, [this, n] {
          running_ = false;
          budget_ += n;
        }});
}

void SimRunner::run_to_frame(int frame) {
  post({false, [this, frame] {
          running_ = false;
          budget_ = 0;
          target_frame_ = frame;
        }});
}

void SimRunner::reset() {
  post({false, [this] {
          announce_limited_pull();
          sim_->reset();
          try {
            make_player();
          } catch (const Error& e) {
            scenario_.reset();
            player_.reset();
            scenario_playing_ = false;
            notice(Notice::Kind::Error, e.what());
          }
          start_over();
        }});
}

void SimRunner::start_over() {
  tool_ = {};
  last_report_ = {};
  last_disp_.reset();
  last_prev_.reset();
  positions_dirty_ = true;
  ++epoch_;
}

void SimRunner::set_params(const Params& p) {
  post({false, [this, p] {
          try {
            // Simulation::set_params keeps the state; it rebuilds the materials (and reloads
            // the backend) when thresholds, material points or anchors changed.
            const bool rebuild = materials_differ(p, sim_->params()) || p.solver.anchors != sim_->params().solver.anchors;
            sim_->set_params(p);
            // New materials, anchors or bricks reload the backend (the state is carried over):
            // download again instead of relying on the reload being exact.
            positions_dirty_ = true;
            if (rebuild) {
              rebuild_model_copy();
              notice(Notice::Kind::Info, "materials rebuilt");
            }
          } catch (const Error& e) {
            notice(Notice::Kind::ParamError, e.what());
          }
        }});
}

void SimRunner::set_scenario(std::optional<Scenario> s) {
  post({false, [this, s] {
          if (s) s->in_lattice_units(sim_->model()).validate(sim_->model());  // throws: the old scenario stays
          announce_limited_pull();
          scenario_ = s;
          sim_->reset();
          make_player();
          start_over();
          running_ = true;
          budget_ = 0;
          target_frame_ = -1;
        }});
}

void SimRunner::replace(std::shared_ptr<Model> model, const Params& p, BackendKind backend, std::string source,
                        std::string done) {
  post({false, [this, model, p, backend, source, done] {
          auto sim = std::make_unique<Simulation>(std::move(*model), p, backend);  // throws: the old one stays
          announce_limited_pull();
          player_.reset();
          sim_ = std::move(sim);
          source_ = source;
          rebuild_model_copy();
          try {
            make_player();
          } catch (const Error& e) {
            scenario_.reset();
            notice(Notice::Kind::Error, std::string("scenario dropped: ") + e.what());
          }
          start_over();
          ++simulation_;
          notice(Notice::Kind::Info, done);
        }});
}

void SimRunner::announce_pending() {
  post({false, [this] { announce_limited_pull(); }});
}

void SimRunner::set_rate(double frames_per_second) {
  post({false, [this, frames_per_second] { rate_ = std::max(0.0, frames_per_second); }});
}

void SimRunner::set_lockstep(bool on) {
  post({false, [this, on] { lockstep_ = on; }});
}

void SimRunner::set_wake(std::function<void()> wake) {
  std::lock_guard lk(mu_);
  wake_ = std::move(wake);
}

void SimRunner::set_before_step(std::function<void(int)> hook) {
  std::lock_guard lk(mu_);
  before_step_ = std::move(hook);
}

// ------------------------------------------------------------------------------------------
// display side

std::shared_ptr<const PublishedFrame> SimRunner::latest() {
  std::shared_ptr<const PublishedFrame> f;
  {
    std::lock_guard lk(mu_);
    f = latest_;
    if (f) taken_seq_ = f->seq;
  }
  cv_.notify_all();  // a lock-step simulation may go on
  return f;
}

std::uint64_t SimRunner::latest_seq() const {
  std::lock_guard lk(mu_);
  return latest_ ? latest_->seq : 0;
}

std::vector<FrameSample> SimRunner::take_samples() {
  std::vector<FrameSample> s;
  std::lock_guard lk(mu_);
  s.swap(samples_);
  return s;
}

std::vector<Notice> SimRunner::take_notices() {
  std::vector<Notice> n;
  std::lock_guard lk(mu_);
  n.swap(notices_);
  return n;
}

void SimRunner::note_display_frame() {
  {
    std::lock_guard lk(display_mu_);
    ++display_frames_;
  }
  display_cv_.notify_all();
}

long SimRunner::wait_for_display_frames(long count, double timeout_s) {
  std::unique_lock lk(display_mu_);
  const long start = display_frames_.load();
  display_cv_.wait_for(lk, std::chrono::duration<double>(timeout_s), [&] {
    bool quit;
    {
      std::lock_guard q(mu_);
      quit = quit_;
    }
    return quit || display_frames_.load() - start >= count;
  });
  return display_frames_.load() - start;
}

// ------------------------------------------------------------------------------------------
// the simulation thread

bool SimRunner::wants_step() const {
  const bool want = running_ || budget_ > 0 || (target_frame_ >= 0 && sim_->frame() < target_frame_);
  if (!want) return false;
  return !(lockstep_ && taken_seq_ < seq_);  // recording: the display has not taken the last frame yet
}

void SimRunner::loop() {
  Clock::time_point next_step = Clock::now();
  std::unique_lock lk(mu_);
  for (;;) {
    // Sleep until a command arrives or a frame is due.
    for (;;) {
      if (quit_) return;
      if (!commands_.empty()) break;
      if (wants_step()) {
        if (rate_ > 0 && Clock::now() < next_step) {
          cv_.wait_until(lk, next_step);
          continue;
        }
        break;
      }
      cv_.wait(lk);
    }
    std::deque<Command> batch;
    batch.swap(commands_);
    lk.unlock();
    for (Command& c : batch) {
      try {
        c.apply();
      } catch (const std::exception& e) {
        notice(Notice::Kind::Error, e.what());
      }
    }
    if (!batch.empty()) {
      track_tool();
      publish(false);
    }
    lk.lock();
    if (quit_) return;
    if (!commands_.empty() || !wants_step() || (rate_ > 0 && Clock::now() < next_step)) continue;
    lk.unlock();
    const Clock::time_point t0 = Clock::now();
    if (rate_ > 0) next_step = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate_));
    try {
      step_frame();
    } catch (const std::exception& e) {
      running_ = false;
      budget_ = 0;
      target_frame_ = -1;
      positions_dirty_ = true;  // the frame may have stopped half-way: show what is there
      notice(Notice::Kind::Error, std::string("simulation stopped: ") + e.what());
      publish(false);
    }
    lk.lock();
  }
}

void SimRunner::step_frame() {
  const Clock::time_point t0 = Clock::now();
  std::function<void(int)> hook;
  {
    std::lock_guard lk(mu_);
    hook = before_step_;
  }
  if (hook) hook(sim_->frame() + 1);
  const bool play = player_ && scenario_playing_ && !player_->done();
  const FrameReport r = play ? player_->step() : sim_->step();
  if (budget_ > 0) --budget_;
  last_report_ = r;
  track_tool();
  publish(true);
  FrameSample s;
  s.epoch = epoch_;
  s.frame = r.frame + 1;
  s.speed = r.mean_speed;
  s.chainmail = static_cast<float>(r.chainmail_ms);
  s.inertia = static_cast<float>(r.inertia_ms);
  s.snapshot = static_cast<float>(r.snapshot_ms);
  s.total = static_cast<float>(r.sim_total_ms);
  s.wall = std::chrono::duration<float, std::milli>(Clock::now() - t0).count();
  std::lock_guard lk(mu_);
  samples_.push_back(s);
  // A display that stopped draining (minimised, stalled) must not grow this without bound.
  if (samples_.size() > 4000) samples_.erase(samples_.begin(), samples_.begin() + 2000);
}

void SimRunner::track_tool() {
  if (sim_->grabbing()) {
    const Index c = sim_->grab_centre();
    if (!tool_.held || tool_.centre != c) {  // a grab started by the scenario
      announce_limited_pull();               // of the grab before it
      tool_ = {};
      tool_.centre = c;
      tool_.held = true;
      tool_.origin = sim_->model().rest(c) + sim_->displacement(c) - sim_->tool_offset();
      tool_.radius = sim_->params().solver.grab_radius;
      if (player_ && scenario_)
        for (std::size_t k = 0; k < scenario_->grabs.size(); ++k)
          if (player_->centre_of(k) == c) tool_.radius = widest_grab_radius(scenario_->grabs[k], sim_->model(), tool_.radius);
      limit_ = {};
    }
    tool_.achieved = sim_->tool_offset();
    tool_.requested = sim_->requested_offset();
    tool_.limited = sim_->tool_limited();
    tool_.shown = true;
    if (tool_.limited) {
      const float shortfall = norm(tool_.requested - tool_.achieved);
      if (!limit_.seen || shortfall >= limit_.shortfall)
        limit_ = {true, limit_.announced, shortfall, tool_.achieved, tool_.requested};
    }
  } else {
    // Released (by the mouse or the scenario): a limited pull is said now, with its largest
    // shortfall; while it lasted, the HUD showed the live figures.
    announce_limited_pull();
    tool_.held = false;
    tool_.limited = false;
  }
}

void SimRunner::announce_limited_pull() {
  if (!limit_.seen || limit_.announced) return;
  limit_.announced = true;
  notice(Notice::Kind::PullLimited, "frame " + std::to_string(sim_->frame()) + ": " +
                                        limited_pull_text(limit_.achieved, limit_.requested, sim_->model().spacing));
}

void SimRunner::publish(bool stepped) {
  auto f = std::make_shared<PublishedFrame>();
  f->epoch = epoch_;
  f->simulation = simulation_;
  f->frame = sim_->frame();
  f->stepped = stepped;
  f->running = running_;
  f->model = model_copy_;
  f->model_id = model_id_;
  // Positions change only in a frame (and on reset or new data): tool moves, parameters and
  // run/pause publish the same buffer again instead of downloading 12 bytes per element.
  if (stepped || positions_dirty_ || !last_disp_) {
    PooledBuffer& buf = acquire_buffer();
    sim_->backend().download_displacements_since(*buf.data, buf.since);
    last_prev_ = stepped ? last_disp_ : last_prev_;
    last_disp_ = buf.data;
    ++positions_id_;
    positions_dirty_ = false;
  }
  f->disp = last_disp_;
  f->prev = last_prev_;
  f->positions_id = positions_id_;
  f->report = last_report_;
  f->params = sim_->params();
  f->backend = sim_->backend().kind();
  f->source = source_;
  f->tool = tool_;
  if (scenario_) {
    f->scenario.loaded = true;
    f->scenario.name = scenario_->name;
    f->scenario.frames = scenario_->frames;
    f->scenario.grabs = scenario_->grabs.size();
    f->scenario.playing = scenario_playing_;
    f->scenario.done = player_ && player_->done();
    f->scenario.player_frame = player_ ? player_->frame() : 0;
  }
  f->reference_centre = reference_centre();
  std::function<void()> wake;
  {
    std::lock_guard lk(mu_);
    f->seq = ++seq_;
    latest_ = std::move(f);
    wake = wake_;
  }
  if (wake) wake();
}

SimRunner::PooledBuffer& SimRunner::acquire_buffer() {
  for (auto& b : pool_)
    if (b.data.use_count() == 1) {  // nobody else holds it: the display let it go
      std::atomic_thread_fence(std::memory_order_acquire);
      return b;
    }
  pool_.push_back({std::make_shared<std::vector<Vec3>>(), 0});
  return pool_.back();
}

void SimRunner::make_player() {
  player_.reset();
  scenario_playing_ = false;
  if (!scenario_) return;
  scenario_->validate(sim_->model());
  player_ = std::make_unique<ScenarioPlayer>(*scenario_, *sim_);
  scenario_playing_ = true;
}

void SimRunner::rebuild_model_copy() {
  model_copy_ = std::make_shared<const Model>(sim_->model());
  ++model_id_;
}

Index SimRunner::reference_centre() const {
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

// ------------------------------------------------------------------------------------------

void RateMeter::add(double t, long count) {
  pts_.emplace_back(t, count);
  while (pts_.size() > 2 && pts_[1].first <= t - window_) pts_.pop_front();
}

double RateMeter::rate() const {
  if (pts_.size() < 2) return 0;
  const double dt = pts_.back().first - pts_.front().first;
  return dt > 0 ? double(pts_.back().second - pts_.front().second) / dt : 0;
}

}  // namespace hpcm::viewer
