// SPEC §8 on a small synthetic phantom: hpcm::run_experiment with the default Params and the
// paper protocol (pull 6 over 20 frames, hold 10, release, record 120; 2,000 settle frames).
// 48 x 48 x 32 is below the 64 along the two longest axes that the motion checks (8.1-8.4, 8.8)
// are held on: they are reported not applicable with that reason; every other check must hold.
//
// Size: 48 x 48 x 32 runs within the test budget (~100-200 s on 2 cores).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <set>
#include <string>

#include "hpcm/experiment.hpp"
#include "hpcm/phantom.hpp"

using namespace hpcm;

namespace {

const Int3 kDims{48, 48, 32};

}  // namespace

TEST(ExperimentChecks, Spec8HoldsOnSmallPhantom) {
  PhantomOptions o;
  o.dims = kDims;
  const Params p;  // defaults
  const Model m = build_model(make_phantom(o), p);
  ExperimentOptions opt;
  opt.settle_frames = 2000;
  const auto t0 = std::chrono::steady_clock::now();
  const ExperimentResult r = run_experiment(m, p, opt);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("experiment %dx%dx%d, settle %d: %.1f s\n", kDims.x, kDims.y, kDims.z, opt.settle_frames, secs);

  // The protocol ran as specified.
  ASSERT_EQ(r.conditions.size(), 3u);
  EXPECT_EQ(r.release_frame, 30);
  EXPECT_EQ(r.recorded_frames, 120);
  for (const auto& c : r.conditions) {
    EXPECT_EQ(c.frames.size(), 150u);
    EXPECT_EQ(c.settle_frames, 2000);
  }

  // Every clause 8.1-8.5, 8.7 and 8.8 is covered by the reported checks.
  const std::set<std::string> expected = {
      "A_no_overshoot",     "B_overshoot",       "B_velocity_sign_changes", "C_overshoot",
      "C_velocity_sign_changes", "C_peak_below_B", "C_auc_below_B",       "C_skin_settles_5pct",
      "C_hierarchy_initial", "C_hierarchy_peak",  "C_hierarchy_auc",         "C_bone_velocity_zero",
      "A_finite",           "A_within_margin",   "A_settled",               "B_finite",
      "B_within_margin",    "B_settled",         "C_finite",                "C_within_margin",
      "C_settled",          "A_links_in_box",    "B_links_in_box",          "C_links_in_box",
      "A_fold_free",        "B_fold_free",       "C_fold_free",             "C_skin_muscle_peak_ratio",
      "C_skin_muscle_auc_ratio", "C_far_field_share_skin_fat", "C_far_field_share_muscle_organ",
      "C_far_field_share_bone", "A_skin_auc_below_C"};
  std::set<std::string> got;
  for (const Check& c : r.checks) got.insert(c.name);
  EXPECT_EQ(got, expected);
  ASSERT_EQ(r.checks.size(), expected.size());

  for (const Check& c : r.checks) {
    std::printf("  %-32s %s %-14s value %-12g threshold %g %s\n", c.name.c_str(), c.spec.c_str(),
                check_status_name(c.status), c.value, c.threshold, c.reason.c_str());
    const bool motion = c.name != "C_bone_velocity_zero" &&
                        (c.spec == "8.1" || c.spec == "8.2" || c.spec == "8.3" || c.spec == "8.4" || c.spec == "8.8");
    if (motion) {
      EXPECT_EQ(c.status, CheckStatus::NotApplicable) << c.name;
      EXPECT_EQ(c.reason, "lattice 48×48×32 below 64 along its two longest axes") << c.name;
      continue;
    }
    EXPECT_TRUE(c.holds()) << "SPEC " << c.spec << " " << c.name << ": " << check_status_name(c.status) << ", value "
                           << c.value << ", threshold " << c.threshold << " (" << c.description << ")";
  }
  EXPECT_TRUE(r.all_hold());
  // The pull of 6 is more than this small phantom's tissue allows (the grab point is near the
  // lattice border): each condition reports one limited stretch, exactly the frames whose
  // tool_limited is set, with the protocol's requested 6 and the largest achieved offset.
  for (const auto& c : r.conditions) {
    int first = -1, last = -1;
    float achieved = 0;
    for (const FrameReport& f : c.frames) {
      achieved = std::max(achieved, f.grab_offset);
      if (!f.tool_limited) continue;
      if (first < 0) first = f.frame;
      last = f.frame;
    }
    ASSERT_GE(first, 0) << c.label << ": the pull was expected to be limited on this phantom";
    ASSERT_EQ(c.limited_pulls.size(), 1u) << c.label;
    const LimitedPull& lp = c.limited_pulls[0];
    EXPECT_EQ(lp.first_frame, first) << c.label;
    EXPECT_EQ(lp.last_frame, last) << c.label;
    EXPECT_NEAR(norm(lp.requested), 6.0f, 1e-5f) << c.label;
    EXPECT_NEAR(norm(lp.achieved), achieved, 1e-5f) << c.label;
    EXPECT_LT(norm(lp.achieved), 6.0f) << c.label;
  }
  for (const auto& c : r.conditions)
    std::printf("  %s skin_fat initial %.6f peak %.6f auc %.6f | muscle_organ %.6f %.6f %.6f | bone %.6f %.6f %.6f\n",
                c.label.c_str(), c.initial[1], c.peak[1], c.auc[1], c.initial[2], c.peak[2], c.auc[2], c.initial[3],
                c.peak[3], c.auc[3]);
}

// Lattices of other sizes and shapes. The overshoot, reversal and hierarchy checks need room
// for the tissue to swing (SPEC §8: held from 64 along the two longest axes); the integrity
// checks (every link in its box after every ChainMail stage, no folded cell at any frame end)
// and settling hold on every lattice the CLI accepts, under all three conditions.
class ExperimentIntegrity : public ::testing::TestWithParam<Int3> {};

TEST_P(ExperimentIntegrity, LinksInBoxFoldFreeAndSettledOnEveryFrame) {
  PhantomOptions o;
  o.dims = GetParam();
  const Params p;
  const Model m = build_model(make_phantom(o), p);
  ExperimentOptions opt;
  opt.settle_frames = 2000;
  const ExperimentResult r = run_experiment(m, p, opt);
  const std::set<std::string> required = {"A_finite",       "B_finite",       "C_finite",       "A_within_margin",
                                          "B_within_margin", "C_within_margin", "A_settled",      "B_settled",
                                          "C_settled",       "A_links_in_box", "B_links_in_box", "C_links_in_box",
                                          "A_fold_free",     "B_fold_free",    "C_fold_free"};
  std::set<std::string> seen;
  for (const Check& c : r.checks) {
    if (!required.count(c.name)) continue;
    seen.insert(c.name);
    EXPECT_TRUE(c.holds()) << o.dims.x << "x" << o.dims.y << "x" << o.dims.z << " " << c.name << ": value " << c.value
                         << ", threshold " << c.threshold;
  }
  EXPECT_EQ(seen, required);
  for (const auto& c : r.conditions) {
    EXPECT_EQ(c.frames.size(), 150u);
    for (std::size_t k = 0; k < c.frames.size(); ++k)
      EXPECT_LE(c.frames[k].max_link_violation, 1e-5f) << c.label << " frame " << k + 1;
  }
}

INSTANTIATE_TEST_SUITE_P(Lattices, ExperimentIntegrity,
                         ::testing::Values(Int3{16, 16, 12}, Int3{32, 32, 24}, Int3{40, 24, 20}),
                         [](const ::testing::TestParamInfo<Int3>& i) {
                           return std::to_string(i.param.x) + "x" + std::to_string(i.param.y) + "x" +
                                  std::to_string(i.param.z);
                         });
