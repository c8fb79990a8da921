// Golden states (issue 34): stored reference outputs of a few short runs, compared bitwise with
// fresh runs on the CPU backend with each kernel path this machine runs (sse2, avx2, avx512) and
// 1, 2 and 3 threads (the short runs on every pair, the 48x48x32 phantom on sse2 x 1, avx2 x 2,
// avx512 x 3), and on the CUDA backend's algorithm run by the host emulation (own files: the
// backends differ in the mean-speed columns; the states must be the same).
// Each file in tests/golden/ holds, per frame, the non-timing columns of frames.csv at full
// precision and, every kHashEvery frames and at the last, an FNV-1a hash of the raw bits of each
// field of the element state (state_digest(), the one place that reads the state). Its comment
// lines name the commit and the parameters that generated it; a run whose parameters differ from
// the stored ones fails before any frame is compared. A failure names the run, configuration,
// frame and column.
//
// A change meant to alter results regenerates every file with one command and commits them with
// the change (the diff of tests/golden/ shows what moved):
//   scripts/regenerate_golden.sh
// which builds this test and runs it with --regenerate (the reference configuration, sse2 on one
// thread, writes; every other configuration must then still match the new files, or the
// regeneration fails). docs/architecture.md, "Golden states".
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "cpu/cpu_backend.hpp"
#include "cpu/kernels.hpp"
#include "cuda/emulation.hpp"
#include "cuda/parity_suite.hpp"
#include "hpcm/config.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/scenario.hpp"
#include "hpcm/simulation.hpp"
#ifdef HPCM_GOLDEN_HAVE_IO
#include "hpcm/io.hpp"
#endif

using namespace hpcm;

namespace {

// --- options of this binary (main() below) ---
bool g_regenerate = false;
std::string g_commit = "unknown (regenerated without scripts/regenerate_golden.sh)";
std::string g_golden_dir = HPCM_SOURCE_DIR "/tests/golden";

constexpr int kHashEvery = 10;  ///< state hashes at frames 9, 19, ... and at the last frame

// --- the element state: read here and nowhere else ---

static_assert(sizeof(Vec3) == 3 * sizeof(float), "Vec3 is hashed as raw bytes: it must have no padding");

template <class T>
std::uint64_t fnv1a(const std::vector<T>& v) {
  static_assert(std::is_trivially_copyable_v<T>, "hash plain values only");
  std::uint64_t h = 0xcbf29ce484222325ull;
  const auto* p = reinterpret_cast<const unsigned char*>(v.data());
  for (std::size_t i = 0; i < v.size() * sizeof(T); ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

struct FieldHash {
  std::string field;
  std::uint64_t hash;
};

/// The element state as the golden files record it: an FNV-1a hash of the raw bits of every
/// field of State, downloaded from the backend through Simulation::state(). A renamed or added
/// field of State changes only this function (then regenerate).
std::vector<FieldHash> state_digest(Simulation& sim) {
  const State& s = sim.state();
  return {{"disp", fnv1a(s.disp)}, {"vel", fnv1a(s.vel)}, {"time", fnv1a(s.time)}, {"flags", fnv1a(s.flags)}};
}

// --- a run's table: frames.csv's non-timing columns at full precision, and state hashes ---

struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

std::string fmt(float v) {
  char b[48];
  std::snprintf(b, sizeof b, "%.9g", v);  // round-trips every float
  return b;
}
std::string fmt(double v) {
  char b[48];
  std::snprintf(b, sizeof b, "%.17g", v);  // round-trips every double
  return b;
}
std::string fmt(long long v) { return std::to_string(v); }
std::string hex(std::uint64_t h) {
  char b[24];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(h));
  return b;
}

/// The columns of frames.csv (apps/hpcm/cmd_run.cpp) without its timings, with their names, and
/// the solver's convergence flag, which frames.csv leaves out.
std::vector<std::pair<std::string, std::string>> report_columns(const FrameReport& r) {
  std::vector<std::pair<std::string, std::string>> c = {
      {"frame", fmt(static_cast<long long>(r.frame))},
      {"stage", r.deform ? "deform" : "idle"},
      {"grab_offset", fmt(r.grab_offset)},
      {"moved_elements", fmt(static_cast<long long>(r.moved_elements))},
      {"active_bricks", fmt(static_cast<long long>(r.active_bricks))},
      {"max_link_violation", fmt(r.max_link_violation)}};
  for (int t = 0; t < kTissueCount; ++t) c.push_back({std::string("mean_speed_") + tissue_name(t), fmt(r.mean_speed[t])});
  for (int t = 0; t < kTissueCount; ++t) c.push_back({std::string("max_speed_") + tissue_name(t), fmt(r.max_speed[t])});
  const std::vector<std::pair<std::string, std::string>> rest = {
      {"propagate_sweeps", fmt(static_cast<long long>(r.propagate_sweeps))},
      {"relax_sweeps", fmt(static_cast<long long>(r.relax_sweeps))},
      {"requested_offset", fmt(r.requested_offset)},
      {"tool_limited", r.tool_limited ? "1" : "0"},
      {"restored_links", fmt(static_cast<long long>(r.restored_links))},
      {"restore_violation", fmt(r.restore_violation)},
      {"min_cell_jacobian", fmt(r.min_cell_jacobian)},
      {"folded_cells", fmt(static_cast<long long>(r.folded_cells))},
      {"active_elements", fmt(static_cast<long long>(r.active_elements))},
      {"grab_offset_mm", fmt(r.grab_offset_mm)},
      {"requested_offset_mm", fmt(r.requested_offset_mm)},
      {"propagate_converged", r.propagate_converged ? "1" : "0"}};
  c.insert(c.end(), rest.begin(), rest.end());
  return c;
}

// --- the runs ---

struct GoldenRun {
  std::string name;         ///< tests/golden/<name>.csv
  std::string description;  ///< written into the file
  std::function<Model(const Params&)> model;  ///< throws / returns an empty model when the data is absent
  Params params;
  std::function<Scenario(const Model&)> scenario;
  bool emulation = true;    ///< also compared on the CUDA host emulation
  bool every_config = true; ///< every kernel path x 1, 2, 3 threads; false: each path and each count once
  std::string data;         ///< input file the run needs ("" for none)
};

Params with_mode(DampingMode mode) {
  Params p;
  p.dynamics.mode = mode;
  return p;
}

Model phantom48(const Params& p) { return cudatest::phantom_model({48, 48, 32}, p); }
// The paper protocol truncated to 60 frames: pull 6 over 20, hold 10, release, 30 frames after.
Scenario paper60(const Model&) { return Scenario::paper_protocol(6.0f, 20, 10, 30); }
const char* kPaper60 = "paper protocol truncated to 60 frames (distance 6, pull 20, hold 10, record 30)";
const std::string kAbdomen = std::string(HPCM_SHARED_DATA) + "/abdomen-ct/abdomen_ct.nii.gz";

std::vector<GoldenRun> runs() {
  std::vector<GoldenRun> r;
  for (DampingMode mode : {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic}) {
    const char* abc = mode == DampingMode::None ? "A" : mode == DampingMode::Simple ? "B" : "C";
    r.push_back({std::string("phantom48_paper60_") + abc,
                 std::string("phantom 48x48x32 (seed 1), ") + kPaper60 + ", dynamics " + damping_mode_name(mode),
                 phantom48, with_mode(mode), paper60, false, false, ""});
  }
  r.push_back({"random_grabs",
               "random heterogeneous lattice 24x20x16 (tests/cuda/parity_suite.hpp random_model, seed 21), "
               "3 random grabs (random_scenario, seed 4) over 90 frames, dynamics viscoelastic",
               [](const Params& p) { return cudatest::random_model({24, 20, 16}, 21, p); }, Params{},
               [](const Model& m) { return cudatest::random_scenario(m, 4, 3, 90); }, true, true, ""});
#ifdef HPCM_GOLDEN_HAVE_IO
  r.push_back({"abdomen_f4",
               "abdomen CT (../shared/data/abdomen-ct/abdomen_ct.nii.gz) down-sampled by 4, " + std::string(kPaper60) +
                   ", dynamics viscoelastic",
               [](const Params& p) {
                 io::InputOptions o;
                 o.downsample = 4;
                 return build_model(io::load_input(kAbdomen, o).lattice, p);
               },
               Params{}, paper60, true, true, kAbdomen});
#endif
  return r;
}

// --- configurations: which backend, kernels and threads play a run ---

struct Config {
  std::string kernels;  ///< CPU kernels; empty: the CUDA host emulation
  int threads = 1;
  bool emulation() const { return kernels.empty(); }
  std::string label() const {
    return emulation() ? std::string("cuda emulation")
                       : "cpu " + kernels + ", " + std::to_string(threads) + " thread" + (threads > 1 ? "s" : "");
  }
};
const Config kReference{"sse2", 1};

// Under the sanitizers (scripts/test.sh runs this test under ASan + UBSan) every run takes the
// short set of configurations: there they look for memory errors, not for another rounding.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

/// The CPU configurations a run is played on, the reference (sse2, 1 thread) first: every
/// kernel path this CPU runs with 1, 2 and 3 threads, or (the longer runs, and every run under
/// a sanitizer) each path and each thread count once: sse2 x 1, avx2 x 2, avx512 x 3.
std::vector<Config> cpu_configs(bool every_config) {
  std::vector<std::string> kernels = {"sse2"};
  if (cpu::cpu_has_avx2()) kernels.push_back("avx2");
  if (cpu::cpu_has_avx512()) kernels.push_back("avx512");
  std::vector<Config> out;
  if (every_config && !kSanitized) {
    for (const std::string& k : kernels)
      for (int t : {1, 2, 3}) out.push_back({k, t});
  } else {
    for (int t : {1, 2, 3}) out.push_back({kernels[std::min<std::size_t>(t - 1, kernels.size() - 1)], t});
  }
  return out;
}

std::unique_ptr<Backend> make_backend_for(const Config& c) {
  if (c.emulation()) return gpu::make_emulated_backend();
  omp_set_num_threads(c.threads);  // the CPU backend takes its thread count when it loads
  auto b = make_backend(BackendKind::Cpu);
  dynamic_cast<cpu::CpuBackend&>(*b).force_kernels(c.kernels);
  return b;
}

/// Plays the run's scenario to its end on configuration c; fills `out` with its table.
void play(const GoldenRun& run, const Model& m, const Config& c, Table& out) {
  Simulation sim(m, run.params, make_backend_for(c));
  if (!c.emulation()) {
    ASSERT_EQ(sim.backend().kernels(), c.kernels) << c.label();
    ASSERT_EQ(sim.backend().threads(), c.threads) << c.label();
  }
  const Scenario sc = run.scenario(sim.model());
  ScenarioPlayer player(sc, sim);
  StepOptions so;  // as `hpcm run` measures by default
  so.link_violation = true;
  so.cell_jacobian = true;
  out = {};
  while (!player.done()) {
    const FrameReport r = player.step(so);
    const bool hashed = r.frame % kHashEvery == kHashEvery - 1 || player.done();
    std::vector<std::string> row;
    for (auto& [name, value] : report_columns(r)) {
      if (out.rows.empty()) out.header.push_back(name);
      row.push_back(value);
    }
    if (hashed || out.rows.empty()) {  // the first frame names the columns
      for (const FieldHash& f : state_digest(sim)) {
        if (out.rows.empty()) out.header.push_back("state_" + f.field + "_fnv1a");
        row.push_back(hashed ? hex(f.hash) : "-");
      }
    } else {
      row.resize(out.header.size(), "-");
    }
    out.rows.push_back(std::move(row));
  }
  ASSERT_EQ(static_cast<int>(out.rows.size()), sc.frames) << c.label();
}

// --- the stored file ---

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? "," : "") + v[i];
  return s;
}
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> v;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) v.push_back(cell);
  return v;
}

std::string path_of(const GoldenRun& run, bool emulation) {
  return g_golden_dir + "/" + run.name + (emulation ? ".cuda_emulation" : "") + ".csv";
}

/// The parameters as comment lines ("# params: key = value").
std::vector<std::string> params_lines(const Params& p) {
  std::vector<std::string> out;
  std::stringstream ss(config::params_to_toml(p));
  for (std::string l; std::getline(ss, l);) {
    l = l.substr(0, l.find('#'));  // the values, not their help text
    while (!l.empty() && l.back() == ' ') l.pop_back();
    if (!l.empty()) out.push_back("# params: " + l);
  }
  return out;
}

struct Stored {
  std::vector<std::string> params;
  Table table;
};

void write_golden(const std::string& path, const GoldenRun& run, const Config& c, const Table& t) {
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), ec);
  std::ofstream f(path);
  ASSERT_TRUE(f) << path << ": cannot open for writing";
  f << "# hpcm golden states: " << run.name << " (tests/golden/test_golden.cpp; regenerate: scripts/regenerate_golden.sh)\n"
    << "# run: " << run.description << "\n"
    << "# generated at commit " << g_commit << " on " << c.label() << "\n"
    << "# columns: frames.csv's non-timing columns at full precision (float %.9g, double %.17g) and propagate_converged;"
       " state_<field>_fnv1a: FNV-1a 64 of the raw bits of that State field at the frame's end, every "
    << kHashEvery << " frames and at the last ('-': not hashed)\n";
  for (const std::string& l : params_lines(run.params)) f << l << "\n";
  f << join(t.header) << "\n";
  for (const auto& row : t.rows) f << join(row) << "\n";
  ASSERT_TRUE(f.flush()) << path << ": write failed";
  std::printf("[golden] wrote %s (%zu frames)\n", path.c_str(), t.rows.size());
}

void read_golden(const std::string& path, Stored& s) {
  std::ifstream f(path);
  ASSERT_TRUE(f) << path << ": no golden file; generate it with scripts/regenerate_golden.sh";
  for (std::string l; std::getline(f, l);) {
    if (l.rfind("# params: ", 0) == 0) s.params.push_back(l);
    if (l.empty() || l[0] == '#') continue;
    if (s.table.header.empty())
      s.table.header = split(l);
    else
      s.table.rows.push_back(split(l));
  }
  ASSERT_FALSE(s.table.header.empty()) << path << ": no header line";
  ASSERT_FALSE(s.table.rows.empty()) << path << ": no frames";
}

/// Bitwise comparison: every cell's text is the exact value. Names the first differing frame
/// and column (and up to 10 more differences); returns the number of differing cells. Columns
/// named in `skip` are not compared.
int compare(const std::string& what, const Table& stored, const Table& fresh, const std::vector<std::string>& skip = {}) {
  if (stored.header != fresh.header) {
    ADD_FAILURE() << what << ": the columns differ\n  stored: " << join(stored.header)
                  << "\n  fresh:  " << join(fresh.header) << "\n  if the change is meant, run scripts/regenerate_golden.sh";
    return 1;
  }
  int diffs = 0;
  if (stored.rows.size() != fresh.rows.size()) {
    ADD_FAILURE() << what << ": " << stored.rows.size() << " frames stored, " << fresh.rows.size() << " played";
    ++diffs;
  }
  const std::size_t n = std::min(stored.rows.size(), fresh.rows.size());
  for (std::size_t f = 0; f < n; ++f) {
    if (stored.rows[f].size() != stored.header.size()) {
      ADD_FAILURE() << what << ": stored frame row " << f << " has " << stored.rows[f].size() << " cells, expected "
                    << stored.header.size();
      return diffs + 1;
    }
    for (std::size_t k = 0; k < stored.header.size(); ++k) {
      if (stored.rows[f][k] == fresh.rows[f][k]) continue;
      if (std::find(skip.begin(), skip.end(), stored.header[k]) != skip.end()) continue;
      if (++diffs <= 10)
        ADD_FAILURE() << what << ": frame " << f << ", column " << stored.header[k] << ": stored " << stored.rows[f][k]
                      << ", fresh " << fresh.rows[f][k] << (diffs == 1 ? " (first difference)" : "");
    }
  }
  if (diffs > 0)
    std::printf("[golden] %s: %d cells differ; if the change is meant, run scripts/regenerate_golden.sh\n", what.c_str(),
                diffs);
  return diffs;
}

/// Columns in which the CUDA backend may differ from the CPU backend while every element's state
/// is the same: the mean speeds are sums reduced in another order. ("Active" is the union of the
/// stages' bricks on both backends: equal.)
std::vector<std::string> backend_dependent_columns() {
  std::vector<std::string> c;
  for (int t = 0; t < kTissueCount; ++t) c.push_back(std::string("mean_speed_") + tissue_name(t));
  return c;
}

class GoldenStates : public ::testing::TestWithParam<GoldenRun> {};

void PrintTo(const GoldenRun& r, std::ostream* os) { *os << r.name; }

/// Compares (or, with --regenerate, first writes) the stored file of `run` on configuration
/// `first`, then checks every configuration in `others` against it.
void check(const GoldenRun& run, const Model& m, const Config& first, const std::vector<Config>& others) {
  const std::string path = path_of(run, first.emulation());
  if (g_regenerate) {
    Table t;
    ASSERT_NO_FATAL_FAILURE(play(run, m, first, t));
    ASSERT_NO_FATAL_FAILURE(write_golden(path, run, first, t));
  }
  Stored stored;
  ASSERT_NO_FATAL_FAILURE(read_golden(path, stored));
  ASSERT_EQ(stored.params, params_lines(run.params))
      << path << ": the run's parameters differ from those that generated the file (a default changed?); "
      << "if the change is meant, run scripts/regenerate_golden.sh";
  std::vector<Config> all = others;
  if (!g_regenerate) all.insert(all.begin(), first);
  for (const Config& c : all) {
    Table fresh;
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_NO_FATAL_FAILURE(play(run, m, c, fresh));
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const int diffs = compare(run.name + " on " + c.label() + " against " + path, stored.table, fresh);
    if (diffs == 0)
      std::printf("[golden] %s on %s: %zu frames bitwise equal (%.2f s)\n", run.name.c_str(), c.label().c_str(),
                  fresh.rows.size(), secs);
  }
}

TEST_P(GoldenStates, BitwiseEqualToTheStoredRun) {
  const GoldenRun& run = GetParam();
  if (!run.data.empty() && !std::filesystem::exists(run.data)) {
    if (g_regenerate) FAIL() << "cannot regenerate " << run.name << ": " << run.data << " is absent; its file is left as it was";
    GTEST_SKIP() << "test data " << run.data << " is absent (../shared/data)";
  }
  const Model m = run.model(run.params);
  const int saved = omp_get_max_threads();
  std::vector<Config> cpu = cpu_configs(run.every_config);
  ASSERT_EQ(cpu.front().label(), kReference.label());
  cpu.erase(cpu.begin());
  ASSERT_NO_FATAL_FAILURE(check(run, m, kReference, cpu));
  if (run.emulation) {
    ASSERT_NO_FATAL_FAILURE(check(run, m, Config{}, {}));
    // The device algorithm moves every element bitwise as the CPU does: the two stored files
    // agree but for the columns that depend on the backend.
    Stored on_cpu, emulated;
    ASSERT_NO_FATAL_FAILURE(read_golden(path_of(run, false), on_cpu));
    ASSERT_NO_FATAL_FAILURE(read_golden(path_of(run, true), emulated));
    EXPECT_EQ(compare(run.name + ": the emulation's stored file against the CPU's", on_cpu.table, emulated.table,
                      backend_dependent_columns()),
              0);
  }
  omp_set_num_threads(saved);
}

INSTANTIATE_TEST_SUITE_P(Runs, GoldenStates, ::testing::ValuesIn(runs()),
                         [](const ::testing::TestParamInfo<GoldenRun>& i) { return i.param.name; });

}  // namespace

// --regenerate: write tests/golden/ from the reference configuration before comparing;
// --commit=TEXT: the commit written into the files; --golden-dir=DIR: read / write there.
int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--regenerate") {
      g_regenerate = true;
    } else if (a.rfind("--commit=", 0) == 0) {
      g_commit = a.substr(9);
    } else if (a.rfind("--golden-dir=", 0) == 0) {
      g_golden_dir = a.substr(13);
    } else {
      std::fprintf(stderr, "%s: unknown argument %s (valid: --regenerate, --commit=TEXT, --golden-dir=DIR, gtest flags)\n",
                   argv[0], argv[i]);
      return 2;
    }
  }
  return RUN_ALL_TESTS();
}
