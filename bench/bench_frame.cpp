// One deformation frame of the paper protocol on the 128x128x75 phantom:
// the parallel brick-sparse solver (OpenMP, 1 and 2 threads) against Gibson's classic
// sequential 3D ChainMail and the sequential Dijkstra-order reference, on the same wave.
//
// Setup (once): phantom 128x128x75, default params (condition C), grab the paper grab centre
// (radius 1.5) and pull it anterior by 6 units over 20 frames; run frames 1..19 through
// hpcm::Simulation. Each timed iteration restores the frame-19 state (untimed) and runs
// frame 20's ChainMail stage: targets -> propagate (-> relax K=8 for the full frame);
// BM_Pipeline_Frame20_2T instead replays frames 1..19 untimed and times Simulation::step.
// Run: hpcm_bench_frame --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include "hpcm/backend.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/simulation.hpp"
#include "solver/reference/dijkstra.hpp"
#include "solver/reference/gibson.hpp"

namespace {

using namespace hpcm;

constexpr int kPullFrames = 20;
constexpr float kPullDistance = 6.0f;

struct Setup {
  Model model;
  Params params;
  State state19;                 ///< state after 19 pull frames (frame-20 X-)
  std::vector<Index> grabbed;    ///< frame-20 FIXED set
  std::vector<Vec3> targets;     ///< frame-20 targets
  std::vector<std::uint8_t> flags;
  // Agreement of the three solvers on this wave (filled once).
  float parallel_vs_dijkstra = -1, gibson_vs_dijkstra = -1, gibson_violation = -1, dijkstra_upstream_violation = -1;
  Index reached_parallel = 0, reached_dijkstra = 0, moved_gibson = 0;
};

float max_abs_diff(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  float d = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int k = 0; k < 3; ++k) d = std::max(d, std::fabs(a[i][k] - b[i][k]));
  return d;
}

const Setup& setup() {
  static const std::unique_ptr<Setup> s = [] {
    auto st = std::make_unique<Setup>();
    PhantomOptions o;
    o.dims = {128, 128, 75};
    st->model = build_model(make_phantom(o), st->params);
    Simulation sim(st->model, st->params);
    const Index centre = paper_grab_centre(st->model);
    sim.grab(centre);
    for (int f = 1; f < kPullFrames; ++f) {
      sim.move_tool(Vec3{0.0f, -kPullDistance * float(f) / kPullFrames, 0.0f});
      sim.step(StepOptions{false, false});
    }
    st->state19 = sim.state();
    st->grabbed = sim.grabbed();
    for (Index i : st->grabbed) st->targets.push_back(Vec3{0.0f, -kPullDistance, 0.0f});
    st->flags.assign(st->grabbed.size(), kGrabbed);
    for (Index i : st->grabbed) st->state19.flags[i] = 0;

    // The same wave with the three solvers.
    auto be = make_backend(BackendKind::Cpu);
    be->load(st->model, st->params, st->state19);
    be->apply_control(Control(st->grabbed, st->targets, st->flags));
    be->snapshot();
    st->reached_parallel = be->propagate().reached;
    std::vector<Vec3> par;
    be->download_displacements(par);
    std::vector<Vec3> dj = st->state19.disp, gb = st->state19.disp;
    reference::DijkstraPropagator d(st->model);
    st->reached_dijkstra = d.run(dj, st->grabbed, st->targets);
    reference::GibsonChainMail g(st->model);
    st->moved_gibson = g.run(gb, st->grabbed, st->targets);
    st->parallel_vs_dijkstra = max_abs_diff(par, dj);
    st->gibson_vs_dijkstra = max_abs_diff(gb, dj);
    st->gibson_violation = max_link_violation(st->model, gb);
    st->dijkstra_upstream_violation = reference::upstream_link_violation(st->model, dj, d.time());
    std::fprintf(stderr,
                 "frame-20 wave: reached parallel %lld, dijkstra %lld, gibson moved %lld; max |parallel - dijkstra| %.3g, "
                 "max |gibson - dijkstra| %.3g; gibson max link violation %.3g; dijkstra upstream violation %.3g\n",
                 (long long)st->reached_parallel, (long long)st->reached_dijkstra, (long long)st->moved_gibson,
                 st->parallel_vs_dijkstra, st->gibson_vs_dijkstra, st->gibson_violation, st->dijkstra_upstream_violation);
    return st;
  }();
  return *s;
}

// Parallel solver, frame-20 ChainMail stage through the Backend. relax: also run relax(K).
// Restoring the state with Backend::load marks every brick that is off rest or carries a
// velocity as hot, so relax(K) here works on far more bricks than in the pipeline (where
// only recently changed bricks are hot): BM_Pipeline_Frame20_2T is the faithful frame.
void run_parallel(benchmark::State& state, int threads, bool relax) {
  const Setup& s = setup();
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
  auto be = make_backend(BackendKind::Cpu);
  Index reached = 0;
  int sweeps = 0, relax_sweeps = 0;
  for (auto _ : state) {
    state.PauseTiming();
    be->load(s.model, s.params, s.state19);  // restore the frame-19 state
    be->apply_control(Control(s.grabbed, s.targets, s.flags));
    state.ResumeTiming();
    be->snapshot();
    const PropagateStats ps = be->propagate();
    if (relax) relax_sweeps = be->relax(s.params.solver.relax_sweeps).sweeps;
    benchmark::DoNotOptimize(ps);
    reached = ps.reached;
    sweeps = ps.sweeps;
  }
  omp_set_num_threads(saved);
  state.counters["reached"] = static_cast<double>(reached);
  state.counters["sweeps"] = sweeps;
  if (relax) state.counters["relax_sweeps"] = relax_sweeps;
  state.counters["diff_vs_dijkstra"] = s.parallel_vs_dijkstra;
}

void BM_Parallel_Frame_2T(benchmark::State& st) { run_parallel(st, 2, true); }
void BM_Parallel_Propagate_2T(benchmark::State& st) { run_parallel(st, 2, false); }
void BM_Parallel_Propagate_1T(benchmark::State& st) { run_parallel(st, 1, false); }

// The whole frame 20 through hpcm::Simulation, exactly as the pipeline runs it (snapshot,
// propagate, relax K, velocity layer), with the pipeline's own bookkeeping of which bricks
// are hot. Restoring means replaying frames 1..19 (untimed), so few iterations.
void BM_Pipeline_Frame20_2T(benchmark::State& state) {
  const Setup& s = setup();
  const int saved = omp_get_max_threads();
  omp_set_num_threads(2);
  double chainmail = 0, total = 0;
  int n = 0;
  for (auto _ : state) {
    state.PauseTiming();
    Simulation sim(s.model, s.params);
    sim.grab(paper_grab_centre(s.model));
    for (int f = 1; f < kPullFrames; ++f) {
      sim.move_tool(Vec3{0.0f, -kPullDistance * float(f) / kPullFrames, 0.0f});
      sim.step(StepOptions{false, false});
    }
    sim.move_tool(Vec3{0.0f, -kPullDistance, 0.0f});
    state.ResumeTiming();
    const FrameReport r = sim.step(StepOptions{false, false});
    benchmark::DoNotOptimize(r);
    chainmail += r.chainmail_ms;
    total += r.sim_total_ms;
    ++n;
  }
  omp_set_num_threads(saved);
  state.counters["chainmail_ms"] = n ? chainmail / n : 0;
  state.counters["sim_total_ms"] = n ? total / n : 0;
}

void BM_Gibson_Propagate(benchmark::State& state) {
  const Setup& s = setup();
  reference::GibsonChainMail g(s.model);
  std::vector<Vec3> pos;
  Index moved = 0;
  for (auto _ : state) {
    state.PauseTiming();
    pos = s.state19.disp;
    state.ResumeTiming();
    moved = g.run(pos, s.grabbed, s.targets);
    benchmark::DoNotOptimize(pos.data());
  }
  state.counters["reached"] = static_cast<double>(moved);
  state.counters["max_violation"] = s.gibson_violation;
  state.counters["diff_vs_dijkstra"] = s.gibson_vs_dijkstra;
}

void BM_Dijkstra_Propagate(benchmark::State& state) {
  const Setup& s = setup();
  reference::DijkstraPropagator d(s.model);
  std::vector<Vec3> pos;
  Index reached = 0;
  for (auto _ : state) {
    state.PauseTiming();
    pos = s.state19.disp;
    state.ResumeTiming();
    reached = d.run(pos, s.grabbed, s.targets);
    benchmark::DoNotOptimize(pos.data());
  }
  state.counters["reached"] = static_cast<double>(reached);
  state.counters["pops"] = static_cast<double>(d.pops());
}

BENCHMARK(BM_Pipeline_Frame20_2T)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_Parallel_Frame_2T)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Parallel_Propagate_2T)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Parallel_Propagate_1T)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Gibson_Propagate)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Dijkstra_Propagate)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
