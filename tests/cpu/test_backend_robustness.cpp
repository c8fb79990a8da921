// Robustness of the CPU backend (issue 29): a refused set_fixed changes nothing, an exception
// in a worker-pool job reaches the caller only after every thread has left the job, and the
// propagation's storage stays bounded over the whole valid range of the link penalty w.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <stdexcept>
#include <thread>

#include "cpu/worker_pool.hpp"
#include "cuda/emulation.hpp"
#include "hpcm/backend_factory.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/simulation.hpp"

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

// ---- set_fixed: validate, then change -------------------------------------------------------

using BackendFactory = std::function<std::unique_ptr<Backend>()>;

void expect_refused_set_fixed_changes_nothing(const BackendFactory& make) {
  const Params p;
  const Model m = small_phantom(p);
  Simulation reference(m, p, make()), sim(m, p, make());
  for (Simulation* s : {&reference, &sim}) {
    s->grab(paper_grab_centre(s->model()));
    pull(*s, 2);
  }
  // A list with an element out of range (first: the device backend reads the list from the
  // end) beside two grabbed ones: refused, naming the element and the range.
  const Index g0 = sim.grabbed().at(0), g1 = sim.grabbed().at(1);
  const std::vector<Index> elements{m.size(), g0, g1};
  const std::vector<Vec3> targets{Vec3{}, Vec3{}, Vec3{}};
  const std::vector<std::uint8_t> flags(3, 0);
  try {
    sim.backend().set_fixed(elements, targets, flags);
    FAIL() << "an out-of-range element was accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("element " + std::to_string(m.size()) + " is out of range [0, " + std::to_string(m.size() - 1) + "]"),
              std::string::npos)
        << msg;
  }
  // The backend's next wave runs with the grab still in force, exactly as without the refused
  // call; so do the next frames.
  for (Simulation* s : {&reference, &sim}) s->backend().propagate();
  EXPECT_TRUE(sim.state().disp == reference.state().disp) << "positions differ from the run without the refused call";
  EXPECT_TRUE(sim.state().flags == reference.state().flags) << "flags differ from the run without the refused call";
  for (Simulation* s : {&reference, &sim}) pull(*s, 3);
  EXPECT_TRUE(sim.state().disp == reference.state().disp) << "positions differ from the run without the refused call";
  EXPECT_TRUE(sim.state().flags == reference.state().flags) << "flags differ from the run without the refused call";
}

TEST(CpuBackendRobustness, RefusedSetFixedKeepsTheOldFixedSet) {
  expect_refused_set_fixed_changes_nothing([] { return make_backend(BackendKind::Cpu); });
}

// The CUDA backend's host side (device_backend.hpp) under the host emulation: same order.
TEST(CpuBackendRobustness, RefusedSetFixedKeepsTheOldFixedSetOnTheDeviceBackend) {
  expect_refused_set_fixed_changes_nothing([] { return gpu::make_emulated_backend(); });
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

}  // namespace
