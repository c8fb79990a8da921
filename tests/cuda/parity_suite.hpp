#pragma once
// Parity of a device backend against the CPU backend (the reference), through the public
// Backend / Simulation API: propagation and relaxation waves with random grabs, and the full
// A/B/C frame pipeline over 200 frames, on the phantom and on random heterogeneous lattices.
// Used by test_cuda_parity.cpp (the CUDA backend, on a GPU) and test_cuda_emulation.cpp (the
// same device algorithm emulated on the host, so it is checked where no GPU exists).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "hpcm/backend_factory.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/scenario.hpp"
#include "hpcm/simulation.hpp"

namespace hpcm::cudatest {

using Factory = std::function<std::unique_ptr<Backend>()>;

/// How close a device backend must come to the CPU reference.
struct Tolerance {
  float pos;         ///< positions, velocities, arrival times, lattice units; 0: bitwise (the same bits)
  float max_speed;   ///< per-tissue max speed per frame
  float mean_speed;  ///< per-tissue mean speed per frame, relative to the larger of 1 and the speed
};
/// A GPU (test_cuda_parity.cpp): SPEC §8.6's 1e-4 lattice units per element.
inline constexpr Tolerance kDeviceTol{1e-4f, 1e-5f, 1e-5f};
/// The device algorithm emulated on the host, compiled like the CPU backend without FMA
/// contraction (test_cuda_emulation.cpp): every element bitwise the CPU's, and so every max
/// speed; the mean speeds are sums reduced in another order (measured up to 1.2e-6 relative
/// after a wave, 2.4e-7 in the frame pipeline).
inline constexpr Tolerance kEmulationTol{0.0f, 0.0f, 2e-6f};

inline Model phantom_model(Int3 dims, const Params& p, std::uint64_t seed = 1) {
  PhantomOptions o;
  o.dims = dims;
  o.seed = seed;
  return build_model(make_phantom(o), p);
}

/// Random heterogeneous lattice: random blobs of air, fat, muscle/organ and bone over soft
/// tissue, plus per-element noise, so every class and every kind of link occurs.
inline Model random_model(Int3 dims, std::uint64_t seed, const Params& p) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  struct Blob {
    float x, y, z, r, hu;
  };
  const float tissues[] = {-1000.0f, -100.0f, 40.0f, 60.0f, 900.0f, -400.0f};
  std::vector<Blob> blobs;
  const int nblobs = 4 + static_cast<int>(U(rng) * 6);
  for (int k = 0; k < nblobs; ++k)
    blobs.push_back({U(rng) * dims.x, U(rng) * dims.y, U(rng) * dims.z, 2.0f + U(rng) * 0.3f * dims.x,
                     tissues[static_cast<int>(U(rng) * 6) % 6]});
  Volume v;
  v.dims = dims;
  v.hu.resize(v.size());
  std::normal_distribution<float> noise(0.0f, 40.0f);
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        float hu = 20.0f;
        for (const Blob& b : blobs) {
          const float dx = x - b.x, dy = y - b.y, dz = z - b.z;
          if (dx * dx + dy * dy + dz * dz <= b.r * b.r) hu = b.hu;
        }
        v.hu[static_cast<std::size_t>(v.index(x, y, z))] = hu + noise(rng);
      }
  return build_model(v, p);
}

/// |a - b|, and the smallest float above 0 for equal values in different bits (-0 and +0), so
/// that a tolerance of 0 means the same bits.
inline float float_diff(float a, float b) {
  const float e = std::fabs(a - b);
  return e == 0.0f && std::memcmp(&a, &b, sizeof a) != 0 ? std::numeric_limits<float>::denorm_min() : e;
}

/// float_diff relative to the larger of 1 and |a|.
inline float relative_diff(float a, float b) { return float_diff(a, b) / std::max(1.0f, std::fabs(a)); }

inline float max_diff(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  if (a.size() != b.size()) return INFINITY;
  float d = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const float e = float_diff(a[i][k], b[i][k]);
      if (!(e <= d)) d = e;  // NaN propagates as failure
    }
  return d;
}

/// Largest |t_a - t_b| over elements reached in both; -1 when the reached sets differ.
inline float time_diff(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return -1.0f;
  float d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::isinf(a[i]) != std::isinf(b[i])) return -1.0f;
    if (!std::isinf(a[i])) {
      const float e = float_diff(a[i], b[i]);
      if (!(e <= d)) d = e;
    }
  }
  return d;
}

inline std::vector<Index> ball(const Model& m, Int3 c, float r) {
  std::vector<Index> out;
  const int R = static_cast<int>(std::floor(r));
  for (int z = std::max(0, c.z - R); z <= std::min(m.dims.z - 1, c.z + R); ++z)
    for (int y = std::max(0, c.y - R); y <= std::min(m.dims.y - 1, c.y + R); ++y)
      for (int x = std::max(0, c.x - R); x <= std::min(m.dims.x - 1, c.x + R); ++x) {
        const float dx = float(x - c.x), dy = float(y - c.y), dz = float(z - c.z);
        if (dx * dx + dy * dy + dz * dz <= r * r) out.push_back(m.index(x, y, z));
      }
  return out;
}

/// Waves straight through the Backend interface: random grab, propagate, relax(K), velocity
/// layer; after each stage both backends must agree. Consecutive waves start from the deformed
/// state of the previous one (the previous wave must be forgotten correctly).
inline void check_waves(const Factory& make_device, const Model& m, const Params& p, std::uint64_t seed, int waves,
                        const std::string& what, const Tolerance& tol = kDeviceTol) {
  auto cpu = make_backend(BackendKind::Cpu);
  auto dev = make_device();
  const State s0 = State::rest(m);
  cpu->load(m, p, s0);
  dev->load(m, p, s0);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  float worst_p = 0, worst_t = 0;
  for (int w = 0; w < waves; ++w) {
    SCOPED_TRACE(what + ", wave " + std::to_string(w));
    const Int3 c{1 + static_cast<int>(U(rng) * (m.dims.x - 2)), 1 + static_cast<int>(U(rng) * (m.dims.y - 2)),
                 1 + static_cast<int>(U(rng) * (m.dims.z - 2))};
    const float r = 0.5f + 2.0f * U(rng);
    const Vec3 off{4.0f * U(rng) - 2.0f, 4.0f * U(rng) - 2.0f, 4.0f * U(rng) - 2.0f};
    std::vector<Vec3> now;
    cpu->download_displacements(now);
    const std::vector<Index> fixed = ball(m, c, r);
    std::vector<Vec3> targets;
    for (Index i : fixed) targets.push_back(now[static_cast<std::size_t>(i)] + off);
    const std::vector<std::uint8_t> fl(fixed.size(), kGrabbed);
    const Control control(fixed, targets, fl);
    cpu->apply_control(control);
    dev->apply_control(control);
    cpu->snapshot();
    dev->snapshot();
    const PropagateStats pc = cpu->propagate(), pd = dev->propagate();
    EXPECT_EQ(pc.reached, pd.reached) << "elements reached by the wave";
    EXPECT_EQ(pc.converged, pd.converged);
    State sc, sd;
    cpu->download(sc);
    dev->download(sd);
    const float dp = max_diff(sc.disp, sd.disp), dt = time_diff(sc.time, sd.time);
    ASSERT_LE(dp, tol.pos) << "propagation positions";
    ASSERT_GE(dt, 0.0f) << "propagation: the sets of reached elements differ";
    ASSERT_LE(dt, tol.pos) << "propagation arrival times";
    EXPECT_EQ(sc.flags, sd.flags);
    worst_p = std::max(worst_p, dp);
    worst_t = std::max(worst_t, dt);

    const int K = p.solver.relax_sweeps;
    const RelaxStats rc = cpu->relax(K), rd = dev->relax(K);
    std::vector<Vec3> xc, xd;
    cpu->download_displacements(xc);
    dev->download_displacements(xd);
    const float dr = max_diff(xc, xd);
    ASSERT_LE(dr, tol.pos) << "relaxation positions (cpu " << rc.sweeps << " sweeps, device " << rd.sweeps << ")";
    worst_p = std::max(worst_p, dr);

    SpeedStats vc, vd;
    cpu->velocity_layer(&vc);
    dev->velocity_layer(&vd);
    cpu->download(sc);
    dev->download(sd);
    const float dl = std::max(max_diff(sc.disp, sd.disp), max_diff(sc.vel, sd.vel));
    ASSERT_LE(dl, tol.pos) << "velocity layer positions / velocities";
    worst_p = std::max(worst_p, dl);
    for (int t = 0; t < kTissueCount; ++t) {
      const float n = static_cast<float>(std::max<Index>(m.class_count[t], 1));
      EXPECT_LE(relative_diff(vc.sum[t] / n, vd.sum[t] / n), tol.mean_speed) << "mean speed, class " << t;
      EXPECT_LE(float_diff(vc.max[t], vd.max[t]), tol.max_speed) << "max speed, class " << t;
    }
  }
  std::printf("[parity] %s: %d waves, max |dx| %.3g, max |dt| %.3g\n", what.c_str(), waves, worst_p, worst_t);
}

/// The link restoration through the Backend interface: a loaded state with links stretched,
/// squeezed and sheared out of their boxes and elements beyond the boundary box must give the
/// same violations and the same restored floats on both backends; the rest state must be left
/// alone by both.
/// The link restoration of state s on `dev` and on the CPU backend: the same statistics and
/// the same restored floats. Returns the CPU's statistics.
inline RestoreStats check_restore_on(Backend& dev, const Model& m, const Params& p, const State& s) {
  auto cpu = make_backend(BackendKind::Cpu);
  cpu->load(m, p, s);
  dev.load(m, p, s);
  const RestoreStats rc = cpu->restore_links(), rd = dev.restore_links();
  EXPECT_EQ(rc.violated_links, rd.violated_links);
  EXPECT_EQ(rc.max_violation, rd.max_violation);
  EXPECT_EQ(rc.moved, rd.moved);
  std::vector<Vec3> xc, xd;
  cpu->download_displacements(xc);
  dev.download_displacements(xd);
  EXPECT_EQ(max_diff(xc, xd), 0.0f) << "restored positions";
  return rc;
}

inline void check_restore(const Factory& make_device, const Model& m, const Params& p, std::uint64_t seed,
                          const std::string& what) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<Index> pick(0, m.size() - 1);
  std::uniform_real_distribution<float> U(-1.5f, 1.5f);
  State broken = State::rest(m);
  for (int k = 0; k < 40; ++k) {
    const auto i = static_cast<std::size_t>(pick(rng));
    broken.disp[i] = broken.disp[i] + Vec3{U(rng), U(rng), U(rng)};
  }
  const Index out = pick(rng);
  broken.disp[static_cast<std::size_t>(out)].x = -3.0f - static_cast<float>(m.coords(out).x);  // X = -3: beyond the boundary box
  for (const bool with_violations : {true, false}) {
    SCOPED_TRACE(what + (with_violations ? ", broken links" : ", rest state"));
    auto dev = make_device();
    const RestoreStats rc = check_restore_on(*dev, m, p, with_violations ? broken : State::rest(m));
    if (with_violations) {
      EXPECT_GT(rc.violated_links, 0) << "the broken state must have links outside their boxes";
      EXPECT_GT(rc.moved, 0);
    } else {
      EXPECT_EQ(rc.violated_links, 0);
    }
  }
}

/// One element pulled 1.5 cells out of its boxes in the middle of a 64x24x16 phantom of 4^3
/// bricks: the restoration moves a region of a few hundred elements around it, reaching bricks
/// beyond the flagged ones and their neighbours (test_cuda_emulation.cpp counts the copies).
struct FarRestoreCase {
  Params p;
  Model m;
  State s;
  Index bricks = 0;
};
inline FarRestoreCase far_restore_case() {
  FarRestoreCase c;
  c.p.solver.brick_size = 4;
  c.m = phantom_model({64, 24, 16}, c.p, 5);
  c.s = State::rest(c.m);
  const auto e = static_cast<std::size_t>(c.m.index(32, 12, 8));
  EXPECT_EQ(c.s.flags[e] & kFixed, 0);
  c.s.disp[e].x += 1.5f;
  c.bricks = (64 / 4) * (24 / 4) * (16 / 4);
  return c;
}

/// The full frame pipeline (Simulation) on both backends, frame by frame.
inline void check_pipeline(const Factory& make_device, const Model& m, const Params& p, const Scenario& sc, int frames,
                           const std::string& what, const Tolerance& tol = kDeviceTol) {
  Simulation a(m, p, make_backend(BackendKind::Cpu));
  Simulation b(m, p, make_device());
  ScenarioPlayer pa(sc, a), pb(sc, b);
  StepOptions so;
  so.speeds = true;
  float worst = 0, worst_curve = 0;
  int deform = 0;
  for (int f = 0; f < frames; ++f) {
    SCOPED_TRACE(what + ", frame " + std::to_string(f));
    const FrameReport ra = pa.done() ? a.step(so) : pa.step(so);
    const FrameReport rb = pb.done() ? b.step(so) : pb.step(so);
    ASSERT_EQ(ra.deform, rb.deform);
    deform += ra.deform;
    EXPECT_EQ(ra.propagate_converged, rb.propagate_converged);
    // "Active" means the same on both backends: the bricks any stage of the frame worked on.
    EXPECT_EQ(ra.active_bricks, rb.active_bricks) << "active bricks";
    EXPECT_EQ(ra.active_elements, rb.active_elements) << "active elements";
    const State& xa = a.state();
    const State& xb = b.state();
    const float d = std::max(max_diff(xa.disp, xb.disp), max_diff(xa.vel, xb.vel));
    ASSERT_LE(d, tol.pos) << "positions / velocities";
    worst = std::max(worst, d);
    for (int t = 0; t < kTissueCount; ++t) {
      const float dm = relative_diff(ra.mean_speed[t], rb.mean_speed[t]), dx = float_diff(ra.max_speed[t], rb.max_speed[t]);
      ASSERT_LE(dm, tol.mean_speed) << "mean speed of class " << tissue_name(t);
      ASSERT_LE(dx, tol.max_speed) << "max speed of class " << tissue_name(t);
      worst_curve = std::max({worst_curve, dm, dx});
    }
  }
  EXPECT_GT(deform, 0) << "the scenario must deform";
  std::printf("[parity] %s: %d frames (%d deform), max |dx| %.3g, max curve diff %.3g\n", what.c_str(), frames, deform,
              worst, worst_curve);
}

/// The CPU backend keeps the still part of the FIXED set (anchors) installed and seeded between
/// controls and re-installs only the tool; the CUDA backend installs every control whole.
/// Controls that change the tool, the anchors (with targets off rest), both, an element both
/// anchored and grabbed, releases and idle frames must give both the same states (within `tol`;
/// the emulation: bit for bit) and flags, every frame.
inline void check_controls(const Factory& make_device, const Tolerance& tol) {
  Params p;
  p.dynamics.mode = DampingMode::Viscoelastic;
  const Model m = phantom_model({32, 28, 16}, p);
  auto cpu = make_backend(BackendKind::Cpu);
  auto dev = make_device();
  const State rest = State::rest(m);
  cpu->load(m, p, rest);
  dev->load(m, p, rest);
  std::vector<Index> bone, border;
  for (Index i = 0; i < m.size(); ++i) {
    if (m.tissue[static_cast<std::size_t>(i)] == static_cast<std::uint8_t>(Tissue::Bone)) bone.push_back(i);
    if (m.coords(i).x == 0) border.push_back(i);
  }
  ASSERT_FALSE(bone.empty());
  const Index centre = paper_grab_centre(m);
  const std::vector<Index> grab = ball(m, m.coords(centre), 1.5f);
  // The FIXED set of a frame: anchors (flags kAnchor) with targets, then the tool pulled by `pull`.
  auto control = [](const std::vector<Index>& anchors, Vec3 anchor_target, const std::vector<Index>& tool, Vec3 pull,
                    bool deform) {
    std::vector<Index> fixed;
    std::vector<Vec3> targets;
    std::vector<std::uint8_t> flags;
    for (Index i : anchors) {
      fixed.push_back(i);
      targets.push_back(anchor_target);
      flags.push_back(kAnchor);
    }
    for (Index i : tool) {
      fixed.push_back(i);
      targets.push_back(pull);
      flags.push_back(kGrabbed);
    }
    return Control(fixed, targets, flags, deform);
  };
  std::vector<Index> tool_on_bone = grab;
  tool_on_bone.push_back(bone.front());  // anchored and grabbed at once
  const std::vector<Index> none;
  int compared = 0;
  for (int f = 0; f < 44; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    const float pull = -0.4f * static_cast<float>(std::min(f, 8) + 1);
    Control c;
    if (f < 10) c = control(bone, Vec3{}, tool_on_bone, Vec3{0.0f, pull, 0.0f}, true);          // pull and hold
    else if (f < 14) c = control(bone, Vec3{}, none, Vec3{}, false);                          // released, idle
    else if (f < 24) c = control(border, Vec3{0.2f, 0.0f, 0.0f}, grab, Vec3{0.0f, pull, 0.3f}, true);  // new anchors off rest
    else if (f < 28) c = control(border, Vec3{0.2f, 0.0f, 0.0f}, none, Vec3{}, true);       // waves without a tool
    else if (f < 34) c = control(bone, Vec3{}, grab, Vec3{0.0f, -1.0f, 0.0f}, f % 2 == 0);  // anchors back
    else c = control(none, Vec3{}, none, Vec3{}, false);                                     // nothing FIXED
    FrameRequest r;
    cpu->step(cpu->resident(), cpu->resident(), c, r);
    dev->step(dev->resident(), dev->resident(), c, r);
    State a, b;
    cpu->download(a);
    dev->download(b);
    ASSERT_LE(max_diff(a.disp, b.disp), tol.pos) << "positions";
    ASSERT_LE(max_diff(a.vel, b.vel), tol.pos) << "velocities";
    const float dt = time_diff(a.time, b.time);
    ASSERT_GE(dt, 0.0f) << "arrival times: finite on one backend, infinite on the other";
    ASSERT_LE(dt, tol.pos) << "arrival times";
    ASSERT_EQ(a.flags, b.flags) << "flags";
    ++compared;
  }
  EXPECT_EQ(compared, 44);
}

/// A scenario of `grabs` random grabs in sequence (pull, hold, release, idle), `frames` long.
inline Scenario random_scenario(const Model& m, std::uint64_t seed, int grabs, int frames) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  Scenario s;
  s.name = "random_grabs";
  s.frames = frames;
  const int slot = frames / std::max(grabs, 1);
  for (int g = 0; g < grabs; ++g) {
    GrabAction a;
    a.centre = Int3{1 + static_cast<int>(U(rng) * (m.dims.x - 2)), 1 + static_cast<int>(U(rng) * (m.dims.y - 2)),
                    1 + static_cast<int>(U(rng) * (m.dims.z - 2))};
    a.radius = 0.8f + 1.5f * U(rng);
    a.start = g * slot;
    const int pull = 5 + static_cast<int>(U(rng) * 15);
    const Vec3 off{6.0f * U(rng) - 3.0f, 6.0f * U(rng) - 3.0f, 6.0f * U(rng) - 3.0f};
    a.path = {{0, {0, 0, 0}}, {pull, off}};
    a.release = std::min(pull + 5, slot - 1);
    s.grabs.push_back(a);
  }
  s.validate(m);
  return s;
}

inline Params with_mode(Params p, DampingMode mode) {
  p.dynamics.mode = mode;
  return p;
}

}  // namespace hpcm::cudatest
