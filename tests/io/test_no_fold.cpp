// No fold, whatever the grab (docs/solver.md, "No fold"): every frame end is fold-free
// (folded_cells == 0, min_cell_jacobian > 0) under A, B and C for lateral, diagonal and corner
// grabs with fast keyframes, a long sequence of random keyframes (fixed seed), tau at both ends
// of its range, on phantoms and on the abdomen CT (f = 4; skipped without ../shared/data).
//
// Each case is also run with HPCM_SKIP_FRAME_END_RESTORE=1 (the pipeline without the frame-end
// restoration, as it was): there the velocity layer folds cells, so every case is one that
// tests something.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

#include "hpcm/hpcm.hpp"
#include "hpcm/io.hpp"

using namespace hpcm;

namespace {

struct FoldFigures {
  int folded_frames = 0;     ///< frames with a folded cell at frame end
  float min_det = 1;         ///< smallest cell corner determinant over every frame end
  Index end_restored = 0;    ///< cells the velocity layer folded and the guard unfolded (all frames)
  float max_link = 0;        ///< largest link violation after the ChainMail stage
};

/// Plays `sc` and `idle` frames more; every frame measures links and cell determinants.
FoldFigures play(const Model& m, const Params& p, const Scenario& sc, int idle) {
  Simulation sim(m, p);
  ScenarioPlayer player(sc, sim);
  StepOptions so;
  so.link_violation = true;
  so.cell_jacobian = true;
  FoldFigures f;
  for (int k = 0; k < sc.frames + idle; ++k) {
    const FrameReport r = player.done() ? sim.step(so) : player.step(so);
    if (r.folded_cells > 0) ++f.folded_frames;
    f.min_det = std::min(f.min_det, r.min_cell_jacobian);
    f.end_restored += r.end_folded_cells;
    f.max_link = std::max(f.max_link, r.max_link_violation);
  }
  return f;
}

/// As play(), without the frame-end restoration (the old pipeline).
FoldFigures play_without_frame_end_restore(const Model& m, const Params& p, const Scenario& sc, int idle) {
  setenv("HPCM_SKIP_FRAME_END_RESTORE", "1", 1);
  const FoldFigures f = play(m, p, sc, idle);
  unsetenv("HPCM_SKIP_FRAME_END_RESTORE");
  return f;
}

Scenario one_grab(std::optional<Int3> centre, std::vector<Keyframe> keys, int release, int frames) {
  Scenario sc;
  sc.name = "no_fold";
  sc.frames = frames;
  GrabAction g;
  g.centre = centre;
  g.path = std::move(keys);
  g.release = release;
  sc.grabs.push_back(g);
  return sc;
}

Keyframe key(int frame, float dx, float dy, float dz) { return Keyframe{frame, Vec3{dx, dy, dz}}; }

/// The lateral grab at every speed: `d` in `fast` frames, back, then 8 up (+z).
Scenario side_back_up(std::optional<Int3> centre, Vec3 d, int fast) {
  return one_grab(centre, {key(fast, d.x, d.y, d.z), key(2 * fast, 0, 0, 0), key(3 * fast, 0, 0, 8)}, 3 * fast + 6,
                  3 * fast + 6);
}

Params with_mode(Params p, DampingMode m) {
  p.dynamics.mode = m;
  return p;
}

Params uniform_tau(float tau) {
  Params p;
  p.material.points = {{-1000.0f, tau, 1.0f}, {1000.0f, tau, 1.0f}};
  p.validate();
  return p;
}

Model phantom(Int3 dims) {
  PhantomOptions o;
  o.dims = dims;
  return build_model(make_phantom(o), Params{});
}

constexpr DampingMode kModes[] = {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic};

/// Every frame end fold-free with the restoration; returns how many runs folded without it.
int expect_fold_free(const Model& m, const Params& base, const Scenario& sc, int idle, const std::string& what) {
  int old_folds = 0;
  for (DampingMode mode : kModes) {
    const Params p = with_mode(base, mode);
    const std::string label = what + ", " + damping_mode_name(mode);
    const FoldFigures now = play(m, p, sc, idle);
    EXPECT_EQ(now.folded_frames, 0) << label << ": smallest determinant " << now.min_det;
    EXPECT_GT(now.min_det, 0.0f) << label;
    EXPECT_LE(now.max_link, 1e-5f) << label;
    const FoldFigures before = play_without_frame_end_restore(m, p, sc, idle);
    std::printf("  %-58s min det %.4f (%lld cells unfolded at frame end); without: %d folded frames, min det %.4f\n",
                label.c_str(), now.min_det, static_cast<long long>(now.end_restored), before.folded_frames,
                before.min_det);
    if (before.folded_frames > 0) ++old_folds;
  }
  return old_folds;
}

}  // namespace

TEST(NoFold, LateralDiagonalAndCornerGrabsOnAPhantom) {
  const Model m = phantom({24, 24, 16});
  const Params p;
  int old_folds = 0;
  const struct {
    const char* name;
    Vec3 d;
  } grabs[] = {{"lateral", {6, 0, 0}}, {"lateral, other side", {-6, 0, 0}}, {"diagonal", {4, -4, 0}},
               {"corner", {4, -4, 4}}, {"corner, down", {-4, 3, -4}}};
  for (const auto& g : grabs)
    for (int fast : {1, 4})
      old_folds += expect_fold_free(m, p, side_back_up(std::nullopt, g.d, fast), 20,
                                    std::string(g.name) + ", keyframes every " + std::to_string(fast));
  EXPECT_GT(old_folds, 0) << "no case folds without the frame-end restoration: the cases test nothing";
}

TEST(NoFold, LongRandomKeyframeSequenceOnAPhantom) {
  const Model m = phantom({24, 24, 16});
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> off(-5.0f, 5.0f);
  std::uniform_int_distribution<int> step(1, 4), cx(4, 19), cy(3, 12), cz(3, 12);
  Scenario sc;
  sc.name = "random_keyframes";
  int start = 0;
  for (int g = 0; g < 3; ++g) {
    GrabAction a;
    a.centre = Int3{cx(rng), cy(rng), cz(rng)};
    a.start = start;
    int f = 0;
    for (int k = 0; k < 12; ++k) {
      f += step(rng);
      a.path.push_back(key(f, off(rng), off(rng), off(rng)));
    }
    a.release = f + 2;
    sc.grabs.push_back(a);
    start += a.release + 5;
  }
  sc.frames = start;
  const int old_folds = expect_fold_free(m, Params{}, sc, 20, "3 grabs x 12 random keyframes");
  EXPECT_GT(old_folds, 0) << "the random sequence does not fold without the frame-end restoration";
}

TEST(NoFold, TauAtItsBounds) {
  // tau = 1 (the upper bound; the shear cap leaves each Jacobian column a margin of 0.02) and a
  // small tau (nearly rigid links).
  PhantomOptions o;
  o.dims = {16, 16, 12};
  const Volume v = make_phantom(o);
  int old_folds = 0;
  for (float tau : {1.0f, 1e-3f}) {
    const Params p = uniform_tau(tau);
    const Model mt = build_model(v, p);
    for (const Vec3 d : {Vec3{0, -6, 0}, Vec3{6, 0, 0}, Vec3{4, -4, 4}})
      old_folds += expect_fold_free(mt, p, side_back_up(std::nullopt, d, 2), 20,
                                    "tau " + std::to_string(tau) + ", pull " + std::to_string(d.x) + "," +
                                        std::to_string(d.y) + "," + std::to_string(d.z));
  }
  EXPECT_GT(old_folds, 0) << "tau = 1 does not fold without the frame-end restoration";
}

TEST(NoFold, AbdomenCtGrabsAtDownsample4) {
  const std::string path = std::string(HPCM_SHARED_DATA) + "/abdomen-ct/abdomen_ct.nii.gz";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "test data " << path << " is absent (../shared/data)";
  io::InputOptions in_opt;
  in_opt.downsample = 4;
  const io::Input in = io::load_input(path, in_opt);
  const Params p;
  const Model m = build_model(in.lattice, p);  // 30 x 25 x 28
  int old_folds = 0;
  // Grab points that folded before: inside the body (13, 9, 19), near the surface (27, 19, 20),
  // and the lateral grab from the paper's grab point.
  old_folds += expect_fold_free(m, p, side_back_up(std::nullopt, {8, 0, 0}, 8), 10, "paper grab point, lateral 8");
  old_folds += expect_fold_free(m, p, side_back_up(Int3{13, 9, 19}, {-4.1f, -6.5f, -2.4f}, 4), 10, "(13, 9, 19), corner");
  old_folds += expect_fold_free(m, p, side_back_up(Int3{27, 19, 20}, {-3.3f, -7.1f, -1.6f}, 5), 10, "(27, 19, 20), corner");
  old_folds += expect_fold_free(m, p, side_back_up(Int3{20, 11, 12}, {4.1f, 4.4f, -5.3f}, 1), 10, "(20, 11, 12), fast");
  EXPECT_GT(old_folds, 0) << "no abdomen case folds without the frame-end restoration";
}
