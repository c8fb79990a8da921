// The CUDA backend's device algorithm (src/cuda/kernels.hpp + device_backend.hpp), run by the
// sequential host emulation of src/cuda/emulation.hpp, against the CPU backend. This runs
// everywhere (no GPU needed): it checks the GPU schedule (single-block bucketed propagation,
// brick lists, red-black relaxation, fused velocity layer, reductions) and the compact link
// layout; test_cuda_parity.cpp runs the same suite on a real device. The emulation must give
// the CPU backend's states bitwise (kEmulationTol): both are compiled without FMA contraction.
#include <omp.h>

#include "cuda/emulation.hpp"
#include "parity_suite.hpp"

using namespace hpcm;
using namespace hpcm::cudatest;

namespace {

// The emulation runs on one host thread; idle OpenMP workers of the CPU reference would spin
// against it on small CI machines, so the reference runs single-threaded here (its result does
// not depend on the thread count).
const bool single_threaded = [] {
  omp_set_num_threads(1);
  return true;
}();

Factory emulated(int blocks = 3) {
  return [blocks] { return gpu::make_emulated_backend(blocks); };
}

TEST(CudaEmulation, MemoryPerElementAtThePapersScale) {
  // 128x128x75 (1,228,800 elements, the paper's lattice): the backend's allocations, counted
  // by the same code that runs on the GPU: 53 bytes per element (positions, X-, velocities,
  // times, tolerances, three 16-bit link indices, tissue, statistics class, flags), the link
  // table and per-brick bookkeeping on top.
  const Params p;
  const Model m = phantom_model({128, 128, 75}, p);
  gpu::DeviceBackend<gpu::EmuExec> b;
  b.load(m, p, State::rest(m));
  const double per = static_cast<double>(b.device_bytes()) / static_cast<double>(m.size());
  std::printf("[parity] device bytes per element at 128x128x75: %.2f\n", per);
  EXPECT_LE(per, 57.0);
  EXPECT_GE(per, 53.0);
}

// The device reads the Model's own link table: a hand-edited link (not the material's value at
// its pair's mean HU) is used as the CPU backend uses it.
TEST(CudaEmulation, DeviceUsesTheModelsLinkTable) {
  const Params p;
  Model m = random_model({10, 9, 8}, 3, p);
  const float tau = m.link_tau[m.link_index[1][5]] * 1.5f;
  m.link_tau.push_back(tau);
  m.link_table.push_back(limits_from_tau(tau, m.link(1, 5).w));
  m.link_index[1][5] = static_cast<std::uint16_t>(m.link_table.size() - 1);
  const auto dev = [] { return std::make_unique<gpu::DeviceBackend<gpu::EmuExec>>(); };
  check_waves([&] { return dev(); }, m, with_mode(p, DampingMode::Viscoelastic), 11, 4, "edited link", kEmulationTol);
}

TEST(CudaEmulation, WavesOnThePhantom) {
  const Params p;
  const Model m = phantom_model({28, 28, 14}, p);
  check_waves(emulated(), m, with_mode(p, DampingMode::Viscoelastic), 1, 6, "phantom 28x28x14", kEmulationTol);
}

TEST(CudaEmulation, WavesOnRandomLattices) {
  for (std::uint64_t seed : {2u, 5u}) {
    Params p;
    p.solver.brick_size = seed == 2 ? 4 : 8;
    p.solver.relax_omega = seed == 2 ? 1.0f : 1.5f;  // plain Gauss-Seidel and over-relaxation
    const Model m = random_model({19, 17, 13}, seed, p);
    check_waves(emulated(seed == 2 ? 1 : 4), m, with_mode(p, DampingMode::Simple), seed * 31, 6,
                "random lattice seed " + std::to_string(seed), kEmulationTol);
  }
}

TEST(CudaEmulation, PropagationListsGrowOnOverflow) {
  // Tiny initial lists: the pending and bucket lists overflow, the wave is put back and rerun
  // with larger lists, and the result must still be the CPU's.
  const Params p;
  const Model m = phantom_model({28, 28, 14}, p);
  const Factory tiny = [] {
    auto b = std::make_unique<gpu::DeviceBackend<gpu::EmuExec>>();
    b->set_initial_list_capacity(8, 2);
    return std::unique_ptr<Backend>(std::move(b));
  };
  check_waves(tiny, m, with_mode(p, DampingMode::Viscoelastic), 1, 4, "tiny initial lists", kEmulationTol);
  // The same waves, counting the reruns.
  gpu::DeviceBackend<gpu::EmuExec> b;
  b.set_initial_list_capacity(8, 2);
  b.load(m, p, State::rest(m));
  const std::vector<Index> fixed = ball(m, Int3{14, 14, 7}, 1.5f);
  std::vector<Vec3> targets;
  for (Index i : fixed) targets.push_back(Vec3{0, -2.0f, 0});
  b.apply_control(Control(fixed, targets, std::vector<std::uint8_t>(fixed.size(), kGrabbed)));
  const PropagateStats st = b.propagate();
  EXPECT_GT(st.reached, 0);
  EXPECT_GT(b.list_regrowths(), 0) << "the tiny lists must have overflowed";
  std::printf("[parity] %d list regrowths for one wave from capacities 8/2\n", b.list_regrowths());
}

TEST(CudaEmulation, StiffUniformLatticeDecidesABucketAgain) {
  // Equal links (w = delta): float rounding of t + w files many pushes back into the bucket
  // just decided. The CPU decides that bucket again, so must the device (found on an H200: the
  // device had dropped them and the wave stopped after 433 of 221,151 elements).
  Params p;
  p.material.points = {{-1000.0f, 0.01f, 0.3f}, {1000.0f, 0.01f, 0.3f}};
  const Model m = phantom_model({40, 40, 12}, p);
  check_waves(emulated(), m, with_mode(p, DampingMode::None), 9, 3, "stiff uniform lattice", kEmulationTol);
}

TEST(CudaEmulation, LinkRestoration) {
  const Params p;
  check_restore(emulated(), phantom_model({24, 20, 12}, p), p, 3, "phantom 24x20x12");
  check_restore(emulated(), random_model({19, 17, 13}, 4, p), p, 4, "random lattice");
}

// "Active bricks" is the union of the bricks the stages of a frame worked on, on both backends
// (it was a per-stage maximum on CUDA): a small pull, its hold and a release.
TEST(CudaEmulation, ActiveBricksAreTheUnionOfTheStagesOnBothBackends) {
  const Params p;
  const Model m = phantom_model({48, 40, 24}, p);
  Simulation cpu(m, p, make_backend(BackendKind::Cpu)), dev(m, p, gpu::make_emulated_backend(2));
  for (Simulation* s : {&cpu, &dev}) s->grab(paper_grab_centre(m));
  // Frame 0 checks every brick (a loaded state is checked once); from frame 1 on, work follows
  // the pull.
  Index quietest = m.size(), busiest = 0;
  for (int f = 0; f < 16; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    if (f < 8)
      for (Simulation* s : {&cpu, &dev}) s->move_tool({0.0f, -0.5f * static_cast<float>(f + 1), 0.0f});
    if (f == 12)
      for (Simulation* s : {&cpu, &dev}) s->release();
    const FrameReport rc = cpu.step(), rd = dev.step();
    ASSERT_EQ(rc.active_bricks, rd.active_bricks);
    ASSERT_EQ(rc.active_elements, rd.active_elements);
    if (f == 0) continue;
    quietest = std::min(quietest, rc.active_bricks);
    busiest = std::max(busiest, rc.active_bricks);
  }
  solver::BrickGrid grid;
  grid.init(m.dims, p.solver.brick_size);
  EXPECT_GT(quietest, 0) << "every frame of the pull and the hold has work";
  EXPECT_LT(quietest, grid.count) << "some bricks must sleep early in the pull";
  EXPECT_GT(busiest, quietest) << "the activity must change over the run";
}

TEST(CudaEmulation, PipelinePaperProtocolABC) {
  const Params p;
  const Model m = phantom_model({24, 24, 12}, p);
  for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic})
    check_pipeline(emulated(), m, with_mode(p, mode), Scenario::paper_protocol(), 200,
                   std::string("phantom, paper protocol, ") + damping_mode_name(mode), kEmulationTol);
}

TEST(CudaEmulation, PipelineRandomGrabsABC) {
  const Params p;
  const Model m = random_model({16, 14, 12}, 21, p);
  const Scenario sc = random_scenario(m, 4, 3, 200);
  for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic})
    check_pipeline(emulated(2), m, with_mode(p, mode), sc, 200,
                   std::string("random lattice, random grabs, ") + damping_mode_name(mode), kEmulationTol);
}

}  // namespace

TEST(CudaEmulation, RestorationCopiesOnlyTheBricksItReaches) {
  // The device copies the bricks the restoration reads: the flagged bricks and their neighbours
  // up front, any other on demand, and no others; the result is still the CPU backend's.
  const FarRestoreCase c = far_restore_case();
  gpu::DeviceBackend<gpu::EmuExec> dev(2);
  const RestoreStats rc = check_restore_on(dev, c.m, c.p, c.s);
  ASSERT_GT(rc.moved, 0);
  std::printf("[restore] moved %lld elements; copied %lld of %lld bricks, %lld on demand\n",
              static_cast<long long>(rc.moved), static_cast<long long>(dev.restore_bricks_copied()),
              static_cast<long long>(c.bricks), static_cast<long long>(dev.restore_cache_misses()));
  EXPECT_GT(dev.restore_cache_misses(), 0) << "the restoration reached past the bricks copied up front";
  EXPECT_LT(dev.restore_bricks_copied(), c.bricks / 4) << "copies follow the restored region, not the lattice";
}

TEST(CudaEmulation, ControlsChangingAnchorsAndToolGiveTheCpuStatesOnBothBackends) {
  check_controls(emulated(2), kEmulationTol);
}
