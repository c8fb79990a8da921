// The free response of one element after release against the closed-form damped recursion of
// the velocity layer (SPEC §5), through the whole frame pipeline (hpcm::Simulation).
//
// Set-up where the ChainMail correction is an exact restoring fraction: a 3x3x3 lattice with
// border anchors (AnchorMode::Border), so the centre element is the only free one and its six
// neighbours stay at rest. With uniform material every neighbour proposes exactly X0, so one
// relaxation sweep with over-relaxation omega moves the centre from x to x + omega*(X0 - x):
//     dX_t = X+ - X- = -k u_t,  k = omega,  u_t = X_t - X0.
// Small displacements (|u| < 0.3) and tau = 0.5 keep every link box inactive and v_max = 10
// keeps the clamp inactive, so the layer is exactly the recursion (dX' = 0 where |dX_t| is
// below dead_zone, the smallest that validation accepts; else dX' = dX_t)
//     simple:        V_{t+1} = a V_t + s dX'
//     viscoelastic:  V_{t+1} = (V_t + s dX') / (1 + b0 + b1 |u_t|)
//     u_{t+1} = u_t + dX_t + beta*rho*V_{t+1}
// from u_0 = the pull offset, V_0 = 0 (the element was FIXED while held). The simulation runs
// in float, the recursion in double; they must agree within 1e-6 for 60 frames.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <ostream>

#include "hpcm/model.hpp"
#include "hpcm/simulation.hpp"

using namespace hpcm;

namespace {

struct Case {
  const char* name;
  DampingMode mode;
  float hu;     ///< uniform HU (selects the class): -1024 air, -100 skin_fat, 40 muscle_organ
  int tissue;
  float omega;  ///< restoring fraction k
  float alpha, b0, b1, beta, rho, inv_mass_muscle;
};

// Readable test names in ctest / gtest output instead of the parameter's bytes.
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

struct D3 {
  double x = 0, y = 0, z = 0;
};
double len(D3 a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

Model cube_model(const Params& p, float hu) {
  Volume v;
  v.dims = {3, 3, 3};
  v.hu.assign(v.size(), hu);
  return build_model(v, p);
}

Params case_params(const Case& c) {
  Params p;
  p.material.points = {{-2000.0f, 0.5f, 1.0f}, {2000.0f, 0.5f, 1.0f}};  // uniform tau = 0.5
  p.solver.anchors = AnchorMode::Border;
  p.solver.relax_sweeps = 1;
  p.solver.relax_omega = c.omega;
  p.solver.relax_threshold = 0.0f;
  p.solver.grab_radius = 0.5f;  // the centre alone
  p.solver.sleep = false;       // the exact recursion: no velocity comes to rest early
  DynamicsParams& d = p.dynamics;
  d.mode = c.mode;
  d.alpha = c.alpha;
  d.b0 = c.b0;
  d.b1 = {0.0f, c.b1, c.b1, c.b1};
  d.inverse_mass = {1.0f, 1.0f, c.inv_mass_muscle, 0.0f};
  d.dead_zone = kMinSettlingDeadZone;  // 0 would never settle: refused by validation
  d.v_max = 10.0f;
  d.beta = c.beta;
  d.rho = {c.rho, c.rho, c.rho, c.rho};
  return p;
}

class FreeResponse : public ::testing::TestWithParam<Case> {};

TEST_P(FreeResponse, MatchesClosedFormRecursion) {
  const Case& c = GetParam();
  const Params p = case_params(c);
  Simulation sim(cube_model(p, c.hu), p);
  const Model& m = sim.model();
  const Index centre = m.index(1, 1, 1);
  ASSERT_EQ(m.tissue[centre], c.tissue);

  // Pull the centre by D over 4 frames, hold 3, release.
  const Vec3 D{0.0625f, -0.09375f, 0.03125f};  // |D| = 0.117
  sim.grab(centre);
  ASSERT_EQ(sim.grabbed().size(), 1u);
  for (int f = 1; f <= 7; ++f) {
    sim.move_tool((std::min(f, 4) / 4.0f) * D);
    sim.step();
    EXPECT_EQ(sim.state().vel[centre], (Vec3{0, 0, 0})) << "held element must have V = 0";
  }
  const Vec3 held = sim.displacement(centre);
  sim.release();

  const double s = p.dynamics.response_scale()[c.tissue];
  const double k = c.omega, g = double(c.beta) * c.rho;
  D3 u{held.x, held.y, held.z}, v{};
  ASSERT_NEAR(len(u), norm(D), 1e-6);
  int sign_changes = 0;
  double max_err = 0, max_u = 0;
  for (int t = 0; t < 60; ++t) {
    const FrameReport r = sim.step();
    ASSERT_FALSE(r.deform);
    // closed form
    const D3 dx{-k * u.x, -k * u.y, -k * u.z};
    const D3 dv = len(dx) < p.dynamics.dead_zone ? D3{} : dx;  // the dead zone
    D3 vn;
    if (c.mode == DampingMode::Simple) {
      vn = {c.alpha * v.x + s * dv.x, c.alpha * v.y + s * dv.y, c.alpha * v.z + s * dv.z};
    } else {
      const double den = 1.0 + c.b0 + c.b1 * len(u);
      vn = {(v.x + s * dv.x) / den, (v.y + s * dv.y) / den, (v.z + s * dv.z) / den};
    }
    const D3 un{u.x + dx.x + g * vn.x, u.y + dx.y + g * vn.y, u.z + dx.z + g * vn.z};
    if ((un.x > 0) != (u.x > 0)) ++sign_changes;
    u = un;
    v = vn;
    max_u = std::max(max_u, len(u));
    // simulation
    const State& st = sim.state();
    const Vec3 xs = st.disp[centre], vs = st.vel[centre];
    const double e = std::max({std::fabs(xs.x - u.x), std::fabs(xs.y - u.y), std::fabs(xs.z - u.z),
                               std::fabs(vs.x - v.x), std::fabs(vs.y - v.y), std::fabs(vs.z - v.z)});
    max_err = std::max(max_err, e);
    ASSERT_LT(e, 1e-6) << c.name << " frame " << t << ": sim u = (" << xs.x << ", " << xs.y << ", " << xs.z
                       << ") V = (" << vs.x << ", " << vs.y << ", " << vs.z << "), closed form u = (" << u.x << ", "
                       << u.y << ", " << u.z << ") V = (" << v.x << ", " << v.y << ", " << v.z << ")";
    // Every other element is anchored at rest and never moves.
    for (Index i = 0; i < m.size(); ++i)
      if (i != centre) ASSERT_EQ(st.disp[i], Vec3{});
  }
  // The case is not trivial: the element overshoots rest and is still moving after a while.
  EXPECT_GE(sign_changes, 2) << c.name;
  // Relaxation target u - k*u stays inside every link box (axial [-0.4, 0.5], shear 0.5).
  EXPECT_LT(max_u * std::fabs(k - 1.0), 0.35) << "displacement left the linear range of the set-up";
  std::printf("%s: max |sim - closed form| = %.3g over 60 frames, %d sign changes, |u_60| = %.3g\n", c.name, max_err,
              sign_changes, len(u));
}

INSTANTIATE_TEST_SUITE_P(
    Layer, FreeResponse,
    ::testing::Values(
        // name, mode, hu, tissue, omega, alpha, b0, b1, beta, rho, inv_mass_muscle
        // omega = 1: u_{t+1} = beta*rho*V_{t+1}, so V_{t+1} = (a - s*beta*rho) V_t (simple) or
        // (1 - s*beta*rho) V_t / (1 + b0 + b1|u_t|) (viscoelastic): a ratio near -0.8, an
        // alternating decay. omega > 1: a genuine second-order (u, V) recursion.
        Case{"simple_skin", DampingMode::Simple, -100.0f, 1, 1.0f, 0.3f, 0, 0, 0.9f, 1.0f, 0.15f},
        Case{"simple_skin_sor", DampingMode::Simple, -100.0f, 1, 1.2f, 0.85f, 0, 0, 1.0f, 1.0f, 0.15f},
        Case{"simple_muscle_sor", DampingMode::Simple, 40.0f, 2, 1.5f, 0.85f, 0, 0, 0.5f, 1.2f, 0.5f},
        Case{"visco_skin", DampingMode::Viscoelastic, -100.0f, 1, 1.0f, 0, 0.05f, 0.5f, 1.4f, 1.0f, 0.15f},
        Case{"visco_air_b1_zero", DampingMode::Viscoelastic, -1024.0f, 0, 1.0f, 0, 0.05f, 0.0f, 1.4f, 1.0f, 0.15f},
        Case{"visco_muscle_sor", DampingMode::Viscoelastic, 40.0f, 2, 1.3f, 0, 0.1f, 0.8f, 0.9f, 0.9f, 0.5f}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

}  // namespace
