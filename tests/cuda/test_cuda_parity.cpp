// CUDA backend parity (issue 5): the CUDA backend against the CPU backend through the public
// API (make_backend(BackendKind::Cuda)), on the phantom and on random heterogeneous lattices
// with random grabs: propagation, relaxation and the full A/B/C pipeline within 1e-4 lattice
// units per element over 200 frames, per-tissue curves within 1e-5.
// Runs only where a CUDA device is present; skips with the reason otherwise (CI has none).
#include "parity_suite.hpp"

#include <cmath>

#include "hpcm/experiment.hpp"

using namespace hpcm;
using namespace hpcm::cudatest;

namespace {

Factory cuda() {
  return [] { return make_backend(BackendKind::Cuda); };
}

#define REQUIRE_CUDA()                                        \
  do {                                                        \
    std::string why;                                          \
    if (!cuda_available(&why)) GTEST_SKIP() << "no CUDA device: " << why; \
  } while (0)

TEST(CudaParity, MemoryPerElement) {
  REQUIRE_CUDA();
  const Params p;
  const Model m = phantom_model({64, 64, 40}, p);
  auto b = make_backend(BackendKind::Cuda);
  b->load(m, p, State::rest(m));
  const DeviceProbe pr = b->probe(2);
  ASSERT_TRUE(pr.available);
  const double per = static_cast<double>(pr.device_bytes) / static_cast<double>(m.size());
  std::printf("[parity] %s: %.2f device bytes per element (%zu bytes, %lld elements)\n", pr.device.c_str(), per,
              pr.device_bytes, static_cast<long long>(m.size()));
  EXPECT_GT(pr.layer_ms, 0.0);
  EXPECT_GT(pr.copy_ms, 0.0);
}

TEST(CudaParity, WavesOnThePhantom) {
  REQUIRE_CUDA();
  const Params p;
  const Model m = phantom_model({48, 48, 32}, p);
  check_waves(cuda(), m, with_mode(p, DampingMode::Viscoelastic), 1, 12, "phantom 48x48x32");
}

TEST(CudaParity, WavesOnRandomLattices) {
  REQUIRE_CUDA();
  for (std::uint64_t seed : {2u, 5u, 8u}) {
    Params p;
    p.solver.brick_size = seed == 2 ? 4 : (seed == 5 ? 8 : 16);
    const Model m = random_model({37, 29, 23}, seed, p);
    check_waves(cuda(), m, with_mode(p, DampingMode::Simple), seed * 31, 10, "random lattice seed " + std::to_string(seed));
  }
}

TEST(CudaParity, PropagationListsGrowOnOverflow) {
  REQUIRE_CUDA();
  Params p;
  p.material.points = {{-1000.0f, 0.01f, 0.3f}, {1000.0f, 0.01f, 0.3f}};
  const Model m = phantom_model({96, 96, 24}, p);
  check_waves(cuda(), m, with_mode(p, DampingMode::None), 9, 3, "stiff uniform lattice");
}

TEST(CudaParity, LinkRestoration) {
  REQUIRE_CUDA();
  const Params p;
  check_restore(cuda(), phantom_model({48, 48, 32}, p), p, 3, "phantom 48x48x32");
  check_restore(cuda(), random_model({37, 29, 23}, 4, p), p, 4, "random lattice");
  // A restoration that reaches bricks beyond the flagged ones (copied on demand).
  const FarRestoreCase c = far_restore_case();
  auto dev = cuda()();
  EXPECT_GT(check_restore_on(*dev, c.m, c.p, c.s).moved, 0);
}

TEST(CudaParity, PipelinePaperProtocolABC) {
  REQUIRE_CUDA();
  const Params p;
  const Model m = phantom_model({48, 48, 32}, p);
  for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic})
    check_pipeline(cuda(), m, with_mode(p, mode), Scenario::paper_protocol(), 200,
                   std::string("phantom, paper protocol, ") + damping_mode_name(mode));
}

TEST(CudaParity, PipelineRandomGrabsABC) {
  REQUIRE_CUDA();
  for (std::uint64_t seed : {21u, 22u}) {
    const Params p;
    const Model m = random_model({32, 28, 24}, seed, p);
    const Scenario sc = random_scenario(m, seed + 100, 3, 200);
    for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic})
      check_pipeline(cuda(), m, with_mode(p, mode), sc, 200,
                     "random lattice " + std::to_string(seed) + ", random grabs, " + damping_mode_name(mode));
  }
}

// SPEC §8.8 from both backends: the far-field split is computed on the host from the frame-end
// positions each backend gives, so the per-class speed sums (near and far) and every check's
// status agree (figures within the parity tolerance).
TEST(CudaParity, ControlsChangingAnchorsAndTool) {
  REQUIRE_CUDA();
  check_controls(cuda(), kDeviceTol);
}

TEST(CudaParity, ExperimentChecksAndFarFieldShares) {
  REQUIRE_CUDA();
  const Params p;
  const Model m = phantom_model({96, 96, 16}, p);
  ExperimentOptions opt;
  opt.scenario = Scenario::paper_protocol(6.0f, 20, 10, 60);
  opt.settle_frames = 50;
  const ExperimentResult cpu = run_experiment(m, p, opt);
  opt.backend = BackendKind::Cuda;
  const ExperimentResult dev = run_experiment(m, p, opt);
  ASSERT_EQ(cpu.checks.size(), dev.checks.size());
  for (std::size_t k = 0; k < cpu.checks.size(); ++k) {
    const Check &a = cpu.checks[k], &b = dev.checks[k];
    EXPECT_EQ(a.name, b.name);
    EXPECT_NEAR(a.value, b.value, 1e-3 + 1e-3 * std::abs(a.value)) << a.name;
    if (a.spec == "8.8") EXPECT_EQ(a.status, b.status) << a.name;
  }
  for (int c = 0; c < 3; ++c)
    for (int t = 0; t < kTissueCount; ++t) {
      const double tol = 1e-6 + 1e-3 * cpu.conditions[c].total_speed_sum[t];
      EXPECT_NEAR(cpu.conditions[c].total_speed_sum[t], dev.conditions[c].total_speed_sum[t], tol) << c << " " << t;
      EXPECT_NEAR(cpu.conditions[c].far_speed_sum[t], dev.conditions[c].far_speed_sum[t], tol) << c << " " << t;
    }
}

}  // namespace
