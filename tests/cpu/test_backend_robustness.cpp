// Robustness of the CPU backend (issues 29, 34): a refused control changes nothing, an exception
// in a worker-pool job reaches the caller only after every thread has left the job, and the
// propagation's storage stays bounded over the whole valid range of the link penalty w.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>

#include "cpu/worker_pool.hpp"
#include "cuda/emulation.hpp"
#include "hpcm/backend_factory.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/simulation.hpp"
#include "solver/bricks.hpp"

using namespace hpcm;

namespace {

Model small_phantom(const Params& p) {
  PhantomOptions o;
  o.dims = {16, 16, 12};
  return build_model(make_phantom(o), p);
}

/// A pull of two cells anterior from the paper's grab point, `frames` frames.
void pull(Simulation& sim, int frames) {
  sim.move_tool({0.0f, -2.0f, 0.0f});
  for (int f = 0; f < frames; ++f) sim.step();
}

// ---- Control: validate, then change ------------------------------------------------------

using BackendFactory = std::function<std::unique_ptr<Backend>()>;

struct BadControl {
  std::string what;      ///< the case
  Control control;
  std::string message;   ///< must appear in the error
};

/// Refused controls beside two grabbed elements: an element out of range (first: the device
/// backend reads the list from the end), a flag that is the backend's own, a NaN and an infinite
/// target, lists of different lengths.
std::vector<BadControl> bad_controls(const Model& m, Index g0, Index g1) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const std::vector<Index> two{g0, g1};
  const std::vector<std::uint8_t> grabbed(2, kGrabbed);
  const std::string n = std::to_string(m.size());
  return {
      {"element out of range", Control({m.size(), g0, g1}, {Vec3{}, Vec3{}, Vec3{}}, {0, kGrabbed, kGrabbed}),
       "element " + n + " is out of range [0, " + std::to_string(m.size() - 1) + "]"},
      {"negative element", Control({g0, -1}, {Vec3{}, Vec3{}}, grabbed), "element -1 is out of range [0, "},
      {"flag kFixed", Control(two, {Vec3{}, Vec3{}}, {kGrabbed, kFixed | kGrabbed}),
       "flags 3 are not one of 0, 2 (grabbed), 4 (anchor), 6 (both)"},
      {"NaN target", Control(two, {Vec3{0.0f, -2.0f, 0.0f}, Vec3{0.0f, nan, 0.0f}}, grabbed),
       "entry 1 (element " + std::to_string(g1) + "): target (0, nan, 0) is not finite"},
      {"infinite target", Control(two, {Vec3{inf, 0.0f, 0.0f}, Vec3{}}, grabbed), "target (inf, 0, 0) is not finite"},
      {"lengths differ", Control(two, {Vec3{}}, grabbed), "2 elements but 1 targets and 2 flags"},
  };
}

void expect_refused_control_changes_nothing(const BackendFactory& make) {
  const Params p;
  const Model m = small_phantom(p);
  Simulation reference(m, p, make()), sim(m, p, make());
  for (Simulation* s : {&reference, &sim}) {
    s->grab(paper_grab_centre(s->model()));
    pull(*s, 2);
  }
  for (const BadControl& bad : bad_controls(m, sim.grabbed().at(0), sim.grabbed().at(1))) {
    SCOPED_TRACE(bad.what);
    Backend& b = sim.backend();
    for (bool through_step : {false, true}) {
      try {
        if (through_step)
          b.step(b.resident(), b.resident(), bad.control, FrameRequest{});
        else
          b.apply_control(bad.control);
        ADD_FAILURE() << "the control was accepted";
      } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(bad.message), std::string::npos) << e.what();
      }
    }
  }
  // The backend's next wave runs with the grab still in force, exactly as without the refused
  // calls; so do the next frames.
  for (Simulation* s : {&reference, &sim}) s->backend().propagate();
  EXPECT_TRUE(sim.state().disp == reference.state().disp) << "positions differ from the run without the refused calls";
  EXPECT_TRUE(sim.state().flags == reference.state().flags) << "flags differ from the run without the refused calls";
  for (Simulation* s : {&reference, &sim}) pull(*s, 3);
  EXPECT_TRUE(sim.state().disp == reference.state().disp) << "positions differ from the run without the refused calls";
  EXPECT_TRUE(sim.state().vel == reference.state().vel) << "velocities differ from the run without the refused calls";
  EXPECT_TRUE(sim.state().flags == reference.state().flags) << "flags differ from the run without the refused calls";
}

TEST(CpuBackendRobustness, RefusedControlKeepsTheOldFixedSet) {
  expect_refused_control_changes_nothing([] { return make_backend(BackendKind::Cpu); });
}

// The CUDA backend's host side (device_backend.hpp) under the host emulation: same order.
TEST(CpuBackendRobustness, RefusedControlKeepsTheOldFixedSetOnTheDeviceBackend) {
  expect_refused_control_changes_nothing([] { return gpu::make_emulated_backend(); });
}

// A backend holds one state and steps it in place: another backend's state is refused.
TEST(CpuBackendRobustness, StepRefusesAStateThatIsNotResident) {
  const Params p;
  const Model m = small_phantom(p);
  auto a = make_backend(BackendKind::Cpu), b = make_backend(BackendKind::Cpu);
  a->load(m, p, State::rest(m));
  b->load(m, p, State::rest(m));
  EXPECT_THROW(a->step(b->resident(), a->resident(), Control{}, FrameRequest{}), Error);
  EXPECT_THROW(a->step(a->resident(), b->resident(), Control{}, FrameRequest{}), Error);
  EXPECT_NO_THROW(a->step(a->resident(), a->resident(), Control{}, FrameRequest{}));
}

// The frame's named phases are timed by the backend's clock; a phase that did not run reads 0.
TEST(CpuBackendRobustness, StepTimesItsNamedPhases) {
  for (const BackendFactory& make : {BackendFactory([] { return make_backend(BackendKind::Cpu); }),
                                     BackendFactory([] { return gpu::make_emulated_backend(); })}) {
    const Params p;
    const Model m = small_phantom(p);
    auto b = make();
    b->load(m, p, State::rest(m));
    const Index g = paper_grab_centre(m);
    const Control pull({g}, {Vec3{0.0f, -1.0f, 0.0f}}, {kGrabbed}, true);
    FrameRequest with_guard, without_guard;
    without_guard.frame_end_guard = false;
    const FrameStats a = b->step(b->resident(), b->resident(), pull, with_guard);
    const FrameStats c = b->step(b->resident(), b->resident(), pull, without_guard);
    for (int ph = 0; ph < kPhaseCount; ++ph) {
      EXPECT_GE(a.phase_ms[ph], 0.0) << phase_name(static_cast<Phase>(ph));
      EXPECT_GE(c.phase_ms[ph], 0.0) << phase_name(static_cast<Phase>(ph));
    }
    EXPECT_GT(a.phase_ms[static_cast<int>(Phase::ChainMail)], 0.0) << "the wave takes time";
    EXPECT_GT(a.phase_ms[static_cast<int>(Phase::FrameEnd)], 0.0) << "the guard ran";
    EXPECT_EQ(c.phase_ms[static_cast<int>(Phase::FrameEnd)], 0.0) << "the guard did not run";
    EXPECT_GT(a.propagate.sweeps, 0) << "a deformation frame propagates";
  }
}

// ---- worker pool: exceptions -------------------------------------------------------------

// Items that take a little time, so that the workers hold items when one throws; `running`
// counts items inside the function: it must be 0 when run() returns or throws.
struct SlowItems {
  std::atomic<int>* running;
  std::atomic<int>* ran;
  std::thread::id thrower;  ///< the thread whose first item throws (default id: none)
  bool throw_on_worker = false;
  void operator()(std::int64_t k) const {
    running->fetch_add(1);
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    const bool on_worker = std::this_thread::get_id() != thrower;
    const bool throws = throw_on_worker ? on_worker : !on_worker;
    ran->fetch_add(1);
    running->fetch_sub(1);
    if (throws && k >= 8) throw std::runtime_error("item " + std::to_string(k) + " failed");
  }
};

void expect_rethrown_after_all_items(bool throw_on_worker) {
  cpu::WorkerPool pool(4);
  std::atomic<int> running{0}, ran{0};
  const SlowItems items{&running, &ran, std::this_thread::get_id(), throw_on_worker};
  bool caught = false;
  try {
    pool.run(400, [&](std::int64_t k) { items(k); });
  } catch (const std::runtime_error& e) {
    caught = true;
    EXPECT_NE(std::string(e.what()).find("failed"), std::string::npos);
  }
  EXPECT_TRUE(caught) << "the exception did not reach the caller";
  EXPECT_EQ(running.load(), 0) << "run() returned while another thread still ran an item";
  // The items after the failure are skipped: the job ends early.
  EXPECT_LT(ran.load(), 400);
  // The pool is usable afterwards and runs every item of the next job.
  std::atomic<int> count{0};
  pool.run(1000, [&](std::int64_t) { count.fetch_add(1); });
  EXPECT_EQ(count.load(), 1000);
}

TEST(WorkerPoolExceptions, ThrownOnAWorkerIsRethrownOnTheCaller) { expect_rethrown_after_all_items(true); }

TEST(WorkerPoolExceptions, ThrownOnTheCallerWaitsForTheWorkers) {
  for (int rep = 0; rep < 5; ++rep) expect_rethrown_after_all_items(false);
}

// ---- propagation over the extreme valid w range ------------------------------------------

double peak_resident_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

TEST(CpuBackendRobustness, ExtremeWRangeKeepsThePropagationSmall) {
  // w from its smallest valid value (air) to its largest (bone): arrival times span 10^8
  // bucket widths and more. The buckets must follow the pending elements, not the times.
  Params p;
  p.material.points = {{-1000.f, 0.5f, 1e-6f}, {-100.f, 0.35f, 100.0f}, {50.f, 0.22f, 1e-6f}, {700.f, 0.005f, 100.0f}};
  ASSERT_NO_THROW(p.validate());
  const Model m = small_phantom(p);
  Simulation sim(m, p);
  sim.grab(paper_grab_centre(m));
  const double before = peak_resident_mb();
  sim.move_tool({0.0f, -3.0f, 0.0f});
  for (int f = 0; f < 4; ++f) {
    const FrameReport r = sim.step();
    EXPECT_GT(r.propagate_sweeps, 0);
  }
  EXPECT_LT(peak_resident_mb() - before, 64.0) << "the propagation grew the process by this much";
  for (const Vec3& x : sim.state().disp)
    for (int a = 0; a < 3; ++a) ASSERT_TRUE(std::isfinite(x[a]));
}


// download_since copies only the bricks written since the host copy's stamp. Over pulls, a
// lateral grab after an idle spell (where the frame-end fold guard acts), releases and idle
// frames, two copies kept at different cadences must equal the full download bit for bit every
// time (fails when a stage writes a brick without marking it, or a new FIXED set's flags are
// not stamped). The lattice is large enough for bricks to sleep, so most copies are partial.
void check_downloads_since(const Params& p, const std::string& what) {
  SCOPED_TRACE(what);
  PhantomOptions o;
  o.dims = {56, 56, 32};
  const Model m = build_model(make_phantom(o), p);
  Simulation sim(m, p);
  Backend& b = sim.backend();
  const Index centre = paper_grab_centre(m);
  const Int3 c = m.coords(centre);
  const Index lateral = m.index(c.x + 6, c.y + 2, c.z + 3);
  auto same_bits = [](const auto& x, const auto& y) {
    return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0;
  };
  solver::BrickGrid grid;
  grid.init(m.dims, p.solver.brick_size);
  State every, third;  // every second and every third frame
  std::vector<Vec3> disp_every;  // every fifth frame
  std::uint64_t since_every = 0, since_third = 0, since_disp = 0;
  int partial = 0;
  for (int f = 0; f < 120; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    if (f == 0) sim.grab(centre);
    if (f < 12) sim.move_tool({0.0f, -0.5f * static_cast<float>(f + 1), 0.0f});
    if (f == 24) sim.release();
    if (f == 80) sim.grab(lateral);
    if (f >= 80 && f < 90) sim.move_tool({0.4f * static_cast<float>(f - 79), 0.0f, 0.2f * static_cast<float>(f - 79)});
    if (f == 100) sim.release();
    if (f == 0 || f == 24 || f == 80 || f == 100) {
      // A new FIXED set is installed at once (flags), before the frame runs.
      State now;
      b.download(now);
      b.download_since(every, since_every);
      ASSERT_TRUE(same_bits(every.flags, now.flags)) << "flags of the new FIXED set";
    }
    const FrameReport r = sim.step();
    partial += r.active_bricks < grid.count;
    // Copies at different cadences; some frames see no download at all (1, 7, 11, ...).
    if (f % 2 != 0 && f % 3 != 0 && f % 5 != 0) continue;
    State full;
    b.download(full);
    if (f % 2 == 0) {
      b.download_since(every, since_every);
      ASSERT_TRUE(same_bits(every.disp, full.disp)) << "displacements";
      ASSERT_TRUE(same_bits(every.vel, full.vel)) << "velocities";
      ASSERT_TRUE(same_bits(every.time, full.time)) << "times";
      ASSERT_TRUE(same_bits(every.flags, full.flags)) << "flags";
    }
    if (f % 3 == 0) {
      b.download_since(third, since_third);
      ASSERT_TRUE(same_bits(third.disp, full.disp) && same_bits(third.vel, full.vel) && same_bits(third.time, full.time) &&
                  same_bits(third.flags, full.flags))
          << "the copy kept every third frame";
    }
    if (f % 5 == 0) {
      b.download_displacements_since(disp_every, since_disp);
      ASSERT_TRUE(same_bits(disp_every, full.disp)) << "displacements alone";
    }
  }
  EXPECT_GT(partial, 5) << "some frames must leave bricks asleep (partial copies)";
  // A new FIXED set changes flags in bricks no stage has touched: the copy must see them.
  auto direct = make_backend(BackendKind::Cpu);
  direct->load(m, p, State::rest(m));
  State copy;
  std::uint64_t since = 0;
  direct->download_since(copy, since);
  const Index corner = m.index(m.dims.x - 1, m.dims.y - 1, m.dims.z - 1);
  direct->apply_control(Control({corner, 0}, {Vec3{}, Vec3{}}, {kAnchor, kGrabbed}));
  State now;
  direct->download(now);
  direct->download_since(copy, since);
  EXPECT_TRUE(same_bits(copy.flags, now.flags)) << "flags of a FIXED set installed where nothing moved";
  EXPECT_NE(now.flags[static_cast<std::size_t>(corner)], 0);
}

TEST(CpuBackendRobustness, DownloadsSinceAStampEqualTheFullDownload) {
  const Params defaults;
  check_downloads_since(defaults, "defaults");
  Params border = defaults;
  border.solver.anchors = AnchorMode::Border;
  border.dynamics.mode = DampingMode::Simple;
  check_downloads_since(border, "border anchors, simple damping");
}

}  // namespace
