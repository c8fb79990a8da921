// The paper-protocol checks on the real CTs beside the checkout (../shared/data), with the
// default Params, as `hpcm experiment --input PATH --downsample F` runs them: the abdomen CT at
// full and half resolution and the DICOM series at half resolution. Every check is asserted to
// hold, or to be not applicable where SPEC §8 says so, except the measured failures listed below
// with their cause and a bound on the figure; a listed failure that starts to hold fails the
// test, so the list cannot go stale. Skipped when the data is absent.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <ostream>
#include <string>

#include "hpcm/experiment.hpp"
#include "hpcm/io.hpp"

using namespace hpcm;

namespace {

struct CtCase {
  const char* name;
  const char* path;  ///< below ../shared/data
  int downsample;
};

void PrintTo(const CtCase& c, std::ostream* os) { *os << c.name; }

struct KnownFailure {
  const char* ct;  ///< CtCase::name
  const char* check;
  double lo, hi;   ///< the check's figure must stay within [lo, hi] (a worsening fails)
  const char* why;
};
// abdomen_f2 (61×50×56) is below 64 along its two longest axes: its motion checks are not
// applicable (SPEC §8), so its former failure (B turning once) is no longer listed.
// SPEC §8.8 (local response) is the abdomen CT's at f = 1, where it holds with every other check.
// On the DICOM series (a 10-slice slab at f = 2, pulled 1.66 units) it is reported: no tissue
// farther than 40 units moves, but skin&fat moves about 9 times muscle&organ (not 10) and A's
// return is 15 % of C's motion (not below 10 %). Bounds about a quarter beyond the measured
// figure (in the comments).
constexpr const char* kSlab =
    "SPEC §8.8 is required on the abdomen CT at f = 1; on the 10-slice DICOM slab it is reported (docs/tuning.md)";
constexpr KnownFailure kKnownFailures[] = {
    {"dicom_f2", "C_skin_muscle_peak_ratio", 6.6, 10.0, kSlab},  // 8.86
    {"dicom_f2", "C_skin_muscle_auc_ratio", 6.5, 10.0, kSlab},   // 8.70
    {"dicom_f2", "A_skin_auc_below_C", 0.1, 0.19, kSlab},        // 0.151
};
/// Entries of kKnownFailures for this CT (each must be met: a renamed check bounds nothing).
int known_failures_listed(const std::string& ct) {
  int n = 0;
  for (const auto& k : kKnownFailures) n += ct == k.ct;
  return n;
}
const KnownFailure* known_failure(const std::string& ct, const std::string& check) {
  for (const auto& k : kKnownFailures)
    if (ct == k.ct && check == k.check) return &k;
  return nullptr;
}

class RealCtExperiment : public ::testing::TestWithParam<CtCase> {};

}  // namespace

TEST_P(RealCtExperiment, ChecksHoldWithDefaults) {
  const CtCase c = GetParam();
  const std::string path = std::string(HPCM_SHARED_DATA) + "/" + c.path;
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "test data " << path << " is absent (../shared/data)";
  io::InputOptions in_opt;
  in_opt.downsample = c.downsample;
  const io::Input in = io::load_input(path, in_opt);
  const Params p;  // defaults, no per-dataset tuning
  const Model m = build_model(in.lattice, p);
  ExperimentOptions opt;
  opt.settle_frames = 2000;
  const auto t0 = std::chrono::steady_clock::now();
  const ExperimentResult r = run_experiment(m, p, opt);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%s: %dx%dx%d, %.1f s\n", c.name, m.dims.x, m.dims.y, m.dims.z, secs);
  ASSERT_EQ(r.conditions.size(), 3u);
  int reported = 0, known_met = 0;
  // SPEC §8: the motion checks are held on lattices >= 64 along the two longest axes (not
  // abdomen_f2's 61×50×56), 8.2 where the achieved pull is >= 0.5; a not-applicable check says why.
  const std::string small_lattice = motion_checks_not_applicable(m.dims);
  for (const Check& k : r.checks) {
    std::printf("  %-32s %s %-14s value %-12g threshold %g %s\n", k.name.c_str(), k.spec.c_str(),
                check_status_name(k.status), k.value, k.threshold, k.reason.c_str());
    ++reported;
    if (k.status == CheckStatus::NotApplicable) {
      EXPECT_FALSE(k.reason.empty()) << k.name;
      if (!small_lattice.empty())
        EXPECT_EQ(k.reason, small_lattice) << c.name << " " << k.name;
      else if (k.spec == "8.2")
        EXPECT_LT(r.conditions[k.name[0] == 'B' ? 1 : 2].max_achieved_offset, kMinSwingPull) << c.name << " " << k.name;
      else
        EXPECT_EQ(k.name, "C_far_field_share_bone") << c.name << ": " << k.reason;
      continue;
    }
    if (const KnownFailure* f = known_failure(c.name, k.name)) {
      ++known_met;
      std::printf("    known failure: %s\n", f->why);
      EXPECT_FALSE(k.holds()) << k.name << " now holds on " << c.name
                              << ": remove it from kKnownFailures and from docs/tuning.md";
      EXPECT_GE(k.value, f->lo) << k.name << " on " << c.name << " got worse";
      EXPECT_LE(k.value, f->hi) << k.name << " on " << c.name << " got worse";
      continue;
    }
    EXPECT_TRUE(k.holds()) << c.name << " " << k.name << ": value " << k.value << ", threshold " << k.threshold << " ("
                           << k.description << ")";
  }
  EXPECT_EQ(reported, 33) << "the paper protocol reports 33 checks (27 of SPEC §8.1-8.7, 6 of §8.8)";
  EXPECT_EQ(known_met, known_failures_listed(c.name)) << "every entry of kKnownFailures for " << c.name
                                                      << " must name a check it reports";
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealCtExperiment,
                         ::testing::Values(CtCase{"abdomen_f1", "abdomen-ct/abdomen_ct.nii.gz", 1},
                                           CtCase{"abdomen_f2", "abdomen-ct/abdomen_ct.nii.gz", 2},
                                           CtCase{"dicom_f2", "abdomen-ct-dicom", 2}),
                         [](const ::testing::TestParamInfo<CtCase>& info) { return std::string(info.param.name); });
