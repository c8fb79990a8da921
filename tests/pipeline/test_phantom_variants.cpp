// The paper-protocol checks on phantom anatomy the defaults were not tuned on (thin tissue over
// bone, thick fat, gas pockets, a CT table, thick slices), with the default Params throughout.
// The checks that hold on every lattice size are asserted on every variant: links in their
// boxes after every ChainMail stage, fold-free, finite, within the margin, settled after the
// idle frames, bone velocity 0, and condition A never moving the grab centre past or away from
// rest after release (over-relaxation is not monotone, so this is measured here frame by frame).
// The overshoot / damping / hierarchy checks need lattices >= 48 per axis (docs/tuning.md);
// they are asserted where the lattice is that large.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ostream>
#include <set>
#include <string>

#include "hpcm/experiment.hpp"
#include "hpcm/phantom.hpp"

using namespace hpcm;

namespace {

struct VariantCase {
  PhantomVariant variant;
  Int3 dims;
};

// Checks measured to fail with the defaults, and why (docs/tuning.md, "Anatomy the defaults
// were not tuned on"). They are reported, not asserted to hold; the test fails if one starts to
// hold, so this list cannot go stale, and if its figure leaves [lo, hi] (about a quarter beyond
// the measured figure), so a worsening fails too.
struct KnownFailure {
  PhantomVariant variant;
  int nx;  ///< lattice size (x) it was measured on
  const char* check;
  double lo, hi;  ///< the check's value must stay within these bounds
  const char* why;
};
// SPEC §3: the per-class means count the body only (the phantom's own outline). The outside air
// in front of the pull, which moved with the skin and was counted as skin&fat (its noise
// straddles -1000 HU), and the table's still foam no longer count; skin&fat is then the skin,
// the subcutaneous and the still visceral fat, while on these small lattices muscle&organ is
// largely the two-element abdominal wall that moves with the skin.
constexpr const char* kBodyOnly =
    "counting the body only (SPEC §3), skin&fat's mean (skin, subcutaneous and still visceral fat) falls below "
    "muscle&organ's (the two-element wall moving with the skin); the pushed outside air no longer counts";
constexpr KnownFailure kKnownFailures[] = {
    {PhantomVariant::ThinTissue, 48, "A_no_overshoot", 0.0, 0.005,
     "the tool moves only 0.02 cells; in the first frame after release over-relaxation carries the grab centre "
     "3.9e-3 cells past rest (19 % of the pull), and four frames later it moves away from rest by 4.8e-6"},
    {PhantomVariant::ThinTissue, 64, "A_no_overshoot", 0.0, 0.0025,
     "the tool moves only 0.02 cells; in the first frame after release over-relaxation carries the grab centre "
     "1.8e-3 cells past rest (8.5 % of the pull)"},
    {PhantomVariant::AirPockets, 48, "C_hierarchy_peak", -0.01, 0.0,
     "muscle&organ's Peak exceeds skin&fat's (-0.0015): the wall over the gas pocket moves with the skin"},
    {PhantomVariant::AirPockets, 48, "C_hierarchy_auc", -0.06, 0.0, kBodyOnly},        // -0.0416
    {PhantomVariant::Table, 48, "C_hierarchy_peak", -0.005, 0.0, kBodyOnly},           // -0.0036
    {PhantomVariant::Table, 48, "C_hierarchy_auc", -0.12, 0.0, kBodyOnly},             // -0.0927
    {PhantomVariant::Anisotropic, 48, "C_hierarchy_peak", -0.0015, 0.0, kBodyOnly},    // -0.00097
    {PhantomVariant::Anisotropic, 48, "C_hierarchy_auc", -0.03, 0.0, kBodyOnly},       // -0.0227
    {PhantomVariant::Table, 64, "C_hierarchy_auc", -0.105, 0.0, kBodyOnly},            // -0.0818
    {PhantomVariant::Standard, 64, "C_hierarchy_auc", -0.035, 0.0, kBodyOnly},         // -0.0275
    {PhantomVariant::Standard, 64, "A_no_overshoot", 0.0, 1.4e-4,
     "four frames after release over-relaxation moves the grab centre away from rest by 1.08e-4 cells (measured "
     "before the body was counted alone too: it does not depend on the statistics)"},
};
const KnownFailure* known_failure(PhantomVariant v, int nx, const std::string& check) {
  for (const auto& k : kKnownFailures)
    if (k.variant == v && k.nx == nx && check == k.check) return &k;
  return nullptr;
}

bool needs_large_lattice(const std::string& spec) {
  return spec == "8.1" || spec == "8.2" || spec == "8.3" || spec == "8.4";
}

// Test names in CTest read as the variant, not as the parameter's bytes.
void PrintTo(const VariantCase& c, std::ostream* os) {
  *os << phantom_variant_name(c.variant) << " " << c.dims.x << "x" << c.dims.y << "x" << c.dims.z;
}

class PhantomVariantExperiment : public ::testing::TestWithParam<VariantCase> {};

}  // namespace

TEST_P(PhantomVariantExperiment, ChecksHoldWithDefaults) {
  const VariantCase vc = GetParam();
  PhantomOptions o;
  o.dims = vc.dims;
  o.variant = vc.variant;
  const Params p;  // defaults, no per-anatomy tuning
  const Model m = build_model(make_phantom(o), p);
  ExperimentOptions opt;
  opt.settle_frames = 2000;
  const auto t0 = std::chrono::steady_clock::now();
  const ExperimentResult r = run_experiment(m, p, opt);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool large = vc.dims.x >= 48 && vc.dims.y >= 48 && vc.dims.z >= 32;
  std::printf("%s %dx%dx%d: %.1f s\n", phantom_variant_name(vc.variant), vc.dims.x, vc.dims.y, vc.dims.z, secs);
  ASSERT_EQ(r.conditions.size(), 3u);

  std::set<std::string> asserted;
  for (const Check& c : r.checks) {
    const bool assert_it = large || !needs_large_lattice(c.spec) || c.name == "A_no_overshoot" ||
                           c.name == "C_bone_velocity_zero";
    std::printf("  %-26s %s %-5s value %-12g threshold %g%s\n", c.name.c_str(), c.spec.c_str(), c.holds ? "holds" : "FAILS",
                c.value, c.threshold, assert_it ? "" : " (not asserted below 48)");
    if (!assert_it) continue;
    asserted.insert(c.name);
    if (const KnownFailure* k = known_failure(vc.variant, vc.dims.x, c.name)) {
      std::printf("    known failure: %s\n", k->why);
      EXPECT_FALSE(c.holds) << c.name << " now holds on " << phantom_variant_name(vc.variant)
                            << ": remove it from kKnownFailures and from docs/tuning.md";
      EXPECT_GE(c.value, k->lo) << c.name << " on " << phantom_variant_name(vc.variant) << " got worse";
      EXPECT_LE(c.value, k->hi) << c.name << " on " << phantom_variant_name(vc.variant) << " got worse";
      continue;
    }
    EXPECT_TRUE(c.holds) << phantom_variant_name(vc.variant) << " " << c.name << ": value " << c.value << ", threshold "
                         << c.threshold << " (" << c.description << ")";
  }
  // The every-lattice checks exist for A, B and C (a renamed check must not pass silently).
  for (const char* cond : {"A", "B", "C"})
    for (const char* what : {"_links_in_box", "_fold_free", "_finite", "_within_margin", "_settled"})
      EXPECT_TRUE(asserted.count(std::string(cond) + what)) << cond << what << " was not reported";

  // Condition A after release, measured here from the grab centre's track: its distance from
  // rest never grows from one frame to the next, and it never passes rest (the side of rest it
  // is on: the sign of its offset along the offset it had at release).
  const ConditionResult& a = r.conditions[0];
  ASSERT_EQ(a.label, "A");
  ASSERT_GT(static_cast<int>(a.centre_track.size()), r.release_frame);
  const Vec3 at_release = a.centre_track[r.release_frame - 1] - a.centre_rest;
  float worst_increase = 0, worst_past_rest = 0, dist_at_release = norm(at_release);
  for (int f = r.release_frame; f < static_cast<int>(a.centre_track.size()); ++f) {
    const float prev = norm(a.centre_track[f - 1] - a.centre_rest), cur = norm(a.centre_track[f] - a.centre_rest);
    worst_increase = std::max(worst_increase, cur - prev);
    worst_past_rest = std::max(worst_past_rest, -dot(a.centre_track[f] - a.centre_rest, at_release) / dist_at_release);
  }
  std::printf("  A: grab centre %.4f from rest at release, largest frame-to-frame increase after it %.3g, largest "
              "distance past rest %.3g; pull achieved %.3f of %.3f requested\n",
              dist_at_release, worst_increase, worst_past_rest, a.max_achieved_offset, a.max_requested_offset);
  // The pull moved the grab centre (on thin-tissue only 0.02 cells: the tool is limited by the
  // anchored plate), and as far as the solver reports for the tool.
  EXPECT_GT(dist_at_release, 0.01f) << "the pull did not move the grab centre";
  EXPECT_NEAR(dist_at_release, a.max_achieved_offset, 1e-3f);
  // The reported check (asserted above, unless a known failure) measures the same thing.
  const auto a_check = std::find_if(r.checks.begin(), r.checks.end(), [](const Check& c) { return c.name == "A_no_overshoot"; });
  ASSERT_NE(a_check, r.checks.end());
  EXPECT_NEAR(std::max({0.0f, worst_increase, worst_past_rest}), a_check->value, 1e-6);
}

INSTANTIATE_TEST_SUITE_P(
    Variants, PhantomVariantExperiment,
    ::testing::Values(VariantCase{PhantomVariant::ThinTissue, {48, 48, 32}}, VariantCase{PhantomVariant::ThickFat, {48, 48, 32}},
                      VariantCase{PhantomVariant::AirPockets, {48, 48, 32}}, VariantCase{PhantomVariant::Table, {48, 48, 32}},
                      VariantCase{PhantomVariant::Anisotropic, {48, 48, 32}},
                      // At 64 (large enough to be held to the motion checks, SPEC §8): the
                      // standard phantom and the table, counting the body only (SPEC §3).
                      VariantCase{PhantomVariant::Standard, {64, 64, 48}}, VariantCase{PhantomVariant::Table, {64, 64, 48}},
                      // Thin tissue stays 2 elements thick at any size; at 64 A is measured to overshoot.
                      VariantCase{PhantomVariant::ThinTissue, {64, 64, 48}}),
    [](const ::testing::TestParamInfo<VariantCase>& info) {
      std::string n = phantom_variant_name(info.param.variant);
      for (char& ch : n)
        if (ch == '-') ch = '_';
      return n + "_" + std::to_string(info.param.dims.x) + "x" + std::to_string(info.param.dims.y) + "x" +
             std::to_string(info.param.dims.z);
    });
