// hpcm bench: the paper protocol timed per stage (Table 3 layout: ChainMail, Inertia, Snapshot,
// SimTotal, medians over frames), elements per second, and on the GPU the fused velocity
// layer's achieved bandwidth against a device-to-device copy measured in the same run.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "cli_common.hpp"
#include "memory_estimate.hpp"
#include "output_dir.hpp"

namespace hpcm::cli {

namespace {

struct BenchOptions {
  VolumeSource source;
  std::string backend = "cpu";
  std::string dynamics = "all";
  std::string params;
  std::string out = "hpcm_bench";
  int frames = 150;
  int warmup = 5;
  int probe_reps = 20;
  bool speeds = false;
  bool awake_reference = false;
};

struct Summary {
  double median = 0, mean = 0, max = 0;
};

Summary summarise(std::vector<double> v) {
  Summary s;
  if (v.empty()) return s;
  double sum = 0;
  for (double x : v) sum += x;
  s.mean = sum / static_cast<double>(v.size());
  std::sort(v.begin(), v.end());
  const std::size_t h = v.size() / 2;
  s.median = v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
  s.max = v.back();
  return s;
}

struct ConditionTiming {
  DampingMode mode;
  std::string label;
  std::vector<FrameReport> frames;
  Summary chainmail, inertia, snapshot, total, total_deform, total_idle;
  // With --awake-reference: the same protocol with every brick awake (solver.sleep = false),
  // stepped alternately with the timed run, and the largest per-element position difference
  // between the two over all frames.
  bool has_awake = false;
  Summary awake_total;
  float max_awake_diff = 0;
};

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) {
      const auto p = line.find(':');
      if (p != std::string::npos) return line.substr(p + 2);
    }
  return "unknown CPU";
}

std::string now_utc() {
  const std::time_t t = std::time(nullptr);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

const char* condition_label(DampingMode m) {
  return m == DampingMode::None ? "A" : (m == DampingMode::Simple ? "B" : "C");
}

/// Runs the paper protocol for `frames` frames (frames past its end run idle).
ConditionTiming run_condition(const Model& model, Params p, DampingMode mode, BackendKind bk, const BenchOptions& o,
                              std::unique_ptr<Simulation>* keep) {
  p.dynamics.mode = mode;
  auto sim = std::make_unique<Simulation>(model, p, bk);
  const Scenario sc = Scenario::paper_protocol();
  ScenarioPlayer player(sc, *sim);
  StepOptions so;
  so.speeds = o.speeds;
  so.link_violation = false;
  ConditionTiming c{mode, condition_label(mode), {}, {}, {}, {}, {}, {}, {}};
  std::vector<double> cm, in, sn, tot, tot_d, tot_i, awake_tot;
  const bool progress = want_progress();
  std::unique_ptr<Simulation> awake;
  std::unique_ptr<ScenarioPlayer> awake_player;
  if (o.awake_reference && p.solver.sleep) {
    Params pa = p;
    pa.solver.sleep = false;
    awake = std::make_unique<Simulation>(model, pa, bk);
    awake_player = std::make_unique<ScenarioPlayer>(sc, *awake);
    c.has_awake = true;
  }
  for (int f = 0; f < o.frames; ++f) {
    if (awake) {  // alternate: the reference frame first, under the same machine load
      const FrameReport ra = awake_player->done() ? awake->step(so) : awake_player->step(so);
      awake_tot.push_back(ra.sim_total_ms);
    }
    const FrameReport r = player.done() ? sim->step(so) : player.step(so);
    if (awake) {  // untimed: both states downloaded and compared
      const std::vector<Vec3>& xs = sim->state().disp;
      const std::vector<Vec3>& xa = awake->state().disp;
      for (std::size_t i = 0; i < xs.size(); ++i) c.max_awake_diff = std::max(c.max_awake_diff, norm(xs[i] - xa[i]));
    }
    c.frames.push_back(r);
    cm.push_back(r.chainmail_ms);
    in.push_back(r.inertia_ms);
    sn.push_back(r.snapshot_ms);
    tot.push_back(r.sim_total_ms);
    (r.deform ? tot_d : tot_i).push_back(r.sim_total_ms);
    if (progress) progress_bar(std::string("bench ") + c.label, f + 1, o.frames);
  }
  c.chainmail = summarise(cm);
  c.inertia = summarise(in);
  c.snapshot = summarise(sn);
  c.total = summarise(tot);
  c.total_deform = summarise(tot_d);
  c.total_idle = summarise(tot_i);
  c.awake_total = summarise(awake_tot);
  if (keep) *keep = std::move(sim);
  return c;
}

nlohmann::json summary_json(const Summary& s) { return {{"median_ms", s.median}, {"mean_ms", s.mean}, {"max_ms", s.max}}; }

}  // namespace

void register_bench(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  auto* cmd = app.add_subcommand(
      "bench", "Time the paper protocol per stage (Table 3: ChainMail, Inertia, Snapshot, SimTotal; medians over frames)");
  add_volume_options(cmd, o->source);
  cmd->add_option("--backend", o->backend, "cpu | cuda")->capture_default_str();
  add_int_option(cmd, "--frames", o->frames, 1, 1'000'000, "Frames per condition (the protocol is 150; more frames run idle)");
  cmd->add_option("--dynamics", o->dynamics, "Conditions to time: all | none (A) | simple (B) | viscoelastic (C)")
      ->capture_default_str();
  cmd->add_option("--params", o->params, "Parameter file (TOML)");
  add_int_option(cmd, "--warmup", o->warmup, 0, 10'000, "Untimed warm-up frames before the timed runs");
  add_int_option(cmd, "--probe-reps", o->probe_reps, 1, 10'000, "Repetitions of the GPU bandwidth probe");
  cmd->add_flag("--speeds", o->speeds, "Include the per-tissue speed reductions in the timed frames");
  cmd->add_flag("--awake-reference", o->awake_reference,
                "Also run every condition with every brick awake (no sleeping), alternating frame by frame with the "
                "timed run: report its SimTotal, the ratio, and the largest position difference between the two");
  cmd->add_option("--out", o->out, "Output folder for bench.csv, bench_frames.csv, bench.json")->capture_default_str();
  cmd->callback([o] {
    const BackendKind bk = parse_backend(o->backend, "--backend");
    std::vector<DampingMode> modes;
    if (o->dynamics == "all")
      modes = {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic};
    else
      modes = {parse_damping_mode(o->dynamics, "--dynamics")};
    if (bk == BackendKind::Cuda) {
      std::string why;
      if (!cuda_available(&why)) throw Error("--backend cuda: no CUDA device: " + why);
    }
    const Params p = load_params_option(o->params);
    check_memory_before_load(o->source, kRunBytesPerElement);
    StagedDir out(o->out, "--out");
    const std::string dir = out.path();
    const Volume v = load_volume(o->source);
    check_lattice_fits(v, o->source, kRunBytesPerElement);
    const Model model = build_model(v, p);
    const Index n = model.size();
    const std::string source =
        (o->source.input.empty() ? std::string("phantom (seed ") + std::to_string(o->source.seed) + ")" : o->source.input) +
        (o->source.downsample > 1 ? " (f = " + std::to_string(o->source.downsample) + ")" : "");

    // Warm-up (module loading, first allocations, graph capture), untimed.
    if (o->warmup > 0) {
      BenchOptions w = *o;
      w.frames = o->warmup;
      run_condition(model, p, modes.back(), bk, w, nullptr);
    }
    std::vector<ConditionTiming> res;
    std::unique_ptr<Simulation> last;
    for (std::size_t k = 0; k < modes.size(); ++k)
      res.push_back(run_condition(model, p, modes[k], bk, *o, k + 1 == modes.size() ? &last : nullptr));
    // Bandwidth probe on the last condition's backend (dense passes; after the timed frames).
    const DeviceProbe probe = last->backend().probe(o->probe_reps);

    // ---- print (Table 3 layout) ----
    const std::string kernels = last->backend().kernels();
    const int sim_threads = last->backend().threads();
    std::string backend_note = kernels.empty() ? "" : " (" + kernels + " kernels)";
    if (sim_threads > 0) backend_note += ", " + std::to_string(sim_threads) + (sim_threads == 1 ? " thread" : " threads");
    std::printf("hpcm bench: %s, %dx%dx%d = %lld elements, backend %s%s%s%s, %d frames per condition%s\n", source.c_str(),
                model.dims.x, model.dims.y, model.dims.z, static_cast<long long>(n), backend_name(bk),
                probe.available ? ": " : "", probe.available ? probe.device.c_str() : "", backend_note.c_str(), o->frames,
                o->speeds ? ", speed reductions on" : "");
    std::printf("Table 3: stage times per frame, median over frames (mean in brackets), ms\n");
    std::printf("%-18s %18s %18s %18s %18s %14s\n", "condition", "ChainMail", "Inertia", "Snapshot", "SimTotal", "elements/s");
    auto cell = [](const Summary& s) {
      char b[64];
      std::snprintf(b, sizeof b, "%.4f (%.4f)", s.median, s.mean);
      return std::string(b);
    };
    for (const auto& c : res) {
      const double eps = c.total.median > 0 ? static_cast<double>(n) / (c.total.median * 1e-3) : 0;
      std::printf("%-18s %18s %18s %18s %18s %14.4g\n", (c.label + " (" + damping_mode_name(c.mode) + ")").c_str(),
                  cell(c.chainmail).c_str(), cell(c.inertia).c_str(), cell(c.snapshot).c_str(), cell(c.total).c_str(), eps);
    }
    for (const auto& c : res)
      std::printf("  %s: SimTotal median over deform frames %.4f ms (%zu frames), over idle frames %.4f ms\n", c.label.c_str(),
                  c.total_deform.median,
                  static_cast<std::size_t>(std::count_if(c.frames.begin(), c.frames.end(), [](const FrameReport& r) { return r.deform; })),
                  c.total_idle.median);
    for (const auto& c : res)
      if (c.has_awake)
        std::printf("  %s: all-awake reference SimTotal median %.4f ms (sleeping: %.4f ms, ratio awake/sleeping %.3f); "
                    "largest position difference over all frames %.3g lattice units\n",
                    c.label.c_str(), c.awake_total.median, c.total.median,
                    c.total.median > 0 ? c.awake_total.median / c.total.median : 0.0, c.max_awake_diff);
    if (probe.available) {
      const double ratio = probe.copy_gbs() > 0 ? probe.layer_gbs() / probe.copy_gbs() : 0;
      std::printf("Velocity layer bandwidth: %.1f GB/s (dense fused pass, %.4f ms, %.0f B/element) vs device-to-device copy "
                  "%.1f GB/s (%.4f ms): %.1f %%\n",
                  probe.layer_gbs(), probe.layer_ms, probe.layer_bytes / static_cast<double>(n), probe.copy_gbs(), probe.copy_ms,
                  100.0 * ratio);
      std::printf("Device memory: %zu bytes held by the backend, %.2f bytes per element\n", probe.device_bytes,
                  static_cast<double>(probe.device_bytes) / static_cast<double>(n));
    } else {
      std::printf("Velocity layer bandwidth: n/a (%s)\n", backend_name(bk));
      std::printf("Device memory: n/a (%s)\n", backend_name(bk));
    }

    // ---- files ----
    std::ostringstream csv;
    csv << "condition,mode,backend,elements,frames,chainmail_median_ms,inertia_median_ms,snapshot_median_ms,"
           "sim_total_median_ms,chainmail_mean_ms,inertia_mean_ms,snapshot_mean_ms,sim_total_mean_ms,"
           "sim_total_deform_median_ms,sim_total_idle_median_ms,elements_per_s,layer_gbs,copy_gbs,layer_copy_ratio,"
           "device_bytes_per_element\n";
    char buf[512];
    for (const auto& c : res) {
      const double eps = c.total.median > 0 ? static_cast<double>(n) / (c.total.median * 1e-3) : 0;
      std::string bw = "n/a,n/a,n/a,n/a";
      if (probe.available) {
        char b2[160];
        std::snprintf(b2, sizeof b2, "%.3f,%.3f,%.4f,%.3f", probe.layer_gbs(), probe.copy_gbs(),
                      probe.copy_gbs() > 0 ? probe.layer_gbs() / probe.copy_gbs() : 0.0,
                      static_cast<double>(probe.device_bytes) / static_cast<double>(n));
        bw = b2;
      }
      std::snprintf(buf, sizeof buf, "%s,%s,%s,%lld,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6g,", c.label.c_str(),
                    damping_mode_name(c.mode), backend_name(bk), static_cast<long long>(n), o->frames, c.chainmail.median,
                    c.inertia.median, c.snapshot.median, c.total.median, c.chainmail.mean, c.inertia.mean, c.snapshot.mean,
                    c.total.mean, c.total_deform.median, c.total_idle.median, eps);
      csv << buf << bw << "\n";
    }
    write_text_file(dir + "/bench.csv", csv.str());
    std::ostringstream fcsv;
    fcsv << "condition,frame,stage,chainmail_ms,inertia_ms,snapshot_ms,sim_total_ms,active_bricks,propagate_sweeps,relax_sweeps,"
            "active_elements\n";
    for (const auto& c : res)
      for (const auto& r : c.frames) {
        std::snprintf(buf, sizeof buf, "%s,%d,%s,%.6f,%.6f,%.6f,%.6f,%lld,%d,%d,%lld\n", c.label.c_str(), r.frame,
                      r.deform ? "deform" : "idle", r.chainmail_ms, r.inertia_ms, r.snapshot_ms, r.sim_total_ms,
                      static_cast<long long>(r.active_bricks), r.propagate_sweeps, r.relax_sweeps,
                      static_cast<long long>(r.active_elements));
        fcsv << buf;
      }
    write_text_file(dir + "/bench_frames.csv", fcsv.str());
    nlohmann::json js;
    js["command"] = "bench";
    js["date"] = now_utc();
    js["source"] = source;
    js["dims"] = {model.dims.x, model.dims.y, model.dims.z};
    js["elements"] = n;
    js["backend"] = backend_name(bk);
    if (!kernels.empty()) js["kernels"] = kernels;
    js["frames"] = o->frames;
    js["warmup_frames"] = o->warmup;
    js["speed_reductions"] = o->speeds;
    js["machine"] = {{"cpu", cpu_model()}, {"hardware_threads", std::thread::hardware_concurrency()}};
    if (sim_threads > 0) js["simulation_threads"] = sim_threads;
    js["timing"] = bk == BackendKind::Cuda ? "CUDA events on the backend's stream" : "std::chrono::steady_clock";
    nlohmann::json conds = nlohmann::json::array();
    for (const auto& c : res) {
      const double eps = c.total.median > 0 ? static_cast<double>(n) / (c.total.median * 1e-3) : 0;
      conds.push_back({{"condition", c.label},
                       {"mode", damping_mode_name(c.mode)},
                       {"chainmail", summary_json(c.chainmail)},
                       {"inertia", summary_json(c.inertia)},
                       {"snapshot", summary_json(c.snapshot)},
                       {"sim_total", summary_json(c.total)},
                       {"sim_total_deform", summary_json(c.total_deform)},
                       {"sim_total_idle", summary_json(c.total_idle)},
                       {"elements_per_s", eps}});
      if (c.has_awake)
        conds.back()["awake_reference"] = {{"sim_total", summary_json(c.awake_total)},
                                           {"max_position_difference", c.max_awake_diff}};
    }
    js["conditions"] = conds;
    if (probe.available) {
      js["device"] = probe.device;
      js["device_bytes"] = probe.device_bytes;
      js["device_bytes_per_element"] = static_cast<double>(probe.device_bytes) / static_cast<double>(n);
      js["bandwidth"] = {{"layer_ms", probe.layer_ms},     {"layer_bytes", probe.layer_bytes}, {"layer_gbs", probe.layer_gbs()},
                         {"copy_ms", probe.copy_ms},       {"copy_bytes", probe.copy_bytes},   {"copy_gbs", probe.copy_gbs()},
                         {"layer_over_copy", probe.copy_gbs() > 0 ? probe.layer_gbs() / probe.copy_gbs() : 0.0},
                         {"repetitions", o->probe_reps}};
    } else {
      js["bandwidth"] = "n/a (" + std::string(backend_name(bk)) + ")";
      js["device_bytes_per_element"] = "n/a (" + std::string(backend_name(bk)) + ")";
    }
    write_json_file(dir + "/bench.json", js);
    out.commit();
    const char* d = out.final_path().c_str();
    std::printf("wrote %s/bench.csv, %s/bench_frames.csv, %s/bench.json\n", d, d, d);
  });
}

}  // namespace hpcm::cli
