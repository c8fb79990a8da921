// hpcm run: play a scenario (default: the paper protocol) and write per-frame metrics.
#include <cstdio>
#include <optional>

#include "cli_common.hpp"
#include "hpcm/config.hpp"
#include "hpcm/folded_frames.hpp"
#include "memory_estimate.hpp"
#include "output_dir.hpp"
#include "pull_limit_notes.hpp"
#include "run_options.hpp"

namespace hpcm::cli {

std::string frames_csv_header() {
  std::string h = "frame,stage,grab_offset,moved_elements,active_bricks,max_link_violation,chainmail_ms,sim_total_ms";
  for (int t = 0; t < kTissueCount; ++t) h += std::string(",mean_speed_") + tissue_name(t);
  for (int t = 0; t < kTissueCount; ++t) h += std::string(",max_speed_") + tissue_name(t);
  h += ",inertia_ms,snapshot_ms,propagate_sweeps,relax_sweeps";
  h += ",requested_offset,tool_limited,restored_links,restore_violation,min_cell_jacobian,folded_cells,active_elements";
  h += ",grab_offset_mm,requested_offset_mm\n";  // new columns go last: readers by position keep working
  return h;
}

std::string frames_csv_row(const FrameReport& r) {
  const std::string at = "frames.csv frame " + std::to_string(r.frame) + ": ";
  require_finite(r.grab_offset, at + "grab_offset");
  require_finite(r.max_link_violation, at + "max_link_violation");
  require_finite(r.chainmail_ms, at + "chainmail_ms");
  require_finite(r.sim_total_ms, at + "sim_total_ms");
  require_finite(r.inertia_ms, at + "inertia_ms");
  require_finite(r.snapshot_ms, at + "snapshot_ms");
  require_finite(r.requested_offset, at + "requested_offset");
  require_finite(r.restore_violation, at + "restore_violation");
  require_finite(r.min_cell_jacobian, at + "min_cell_jacobian");
  require_finite(r.grab_offset_mm, at + "grab_offset_mm");
  require_finite(r.requested_offset_mm, at + "requested_offset_mm");
  for (int t = 0; t < kTissueCount; ++t) {
    require_finite(r.mean_speed[t], at + "mean_speed_" + tissue_name(t));
    require_finite(r.max_speed[t], at + "max_speed_" + tissue_name(t));
  }
  char buf[256];
  std::string s;
  std::snprintf(buf, sizeof buf, "%d,%s,%.6g,%lld,%lld,%.6g,%.6f,%.6f", r.frame, r.deform ? "deform" : "idle", r.grab_offset,
                static_cast<long long>(r.moved_elements), static_cast<long long>(r.active_bricks), r.max_link_violation,
                r.chainmail_ms, r.sim_total_ms);
  s += buf;
  for (int t = 0; t < kTissueCount; ++t) {
    std::snprintf(buf, sizeof buf, ",%.9g", r.mean_speed[t]);
    s += buf;
  }
  for (int t = 0; t < kTissueCount; ++t) {
    std::snprintf(buf, sizeof buf, ",%.9g", r.max_speed[t]);
    s += buf;
  }
  std::snprintf(buf, sizeof buf, ",%.6f,%.6f,%d,%d", r.inertia_ms, r.snapshot_ms, r.propagate_sweeps, r.relax_sweeps);
  s += buf;
  std::snprintf(buf, sizeof buf, ",%.6g,%d,%lld,%.6g,%.6g,%lld,%lld,%.6g,%.6g\n", r.requested_offset, r.tool_limited ? 1 : 0,
                static_cast<long long>(r.restored_links), r.restore_violation, r.min_cell_jacobian,
                static_cast<long long>(r.folded_cells), static_cast<long long>(r.active_elements), r.grab_offset_mm,
                r.requested_offset_mm);
  return s + buf;
}

Params resolve_params(const RunOptions& o) {
  Params p = load_params_option(o.params);
  if (!o.dynamics.empty()) p.dynamics.mode = parse_damping_mode(o.dynamics, "--dynamics");
  p.validate();
  return p;
}

Scenario resolve_scenario(const RunOptions& o) {
  if (o.scenario.empty() || o.scenario == "paper") return Scenario::paper_protocol();
  return config::load_scenario(o.scenario);
}

std::string scenario_label(const std::string& path) {
  return path.empty() || path == "paper" ? std::string("the paper protocol") : "scenario " + path;
}

void rethrow_in_scenario(const Error& e, const Scenario& sc, const std::string& label, int frame) {
  std::string where = label;
  const ScenarioPlace p = scenario_place(sc, frame);
  if (!p.text.empty()) where += ", " + p.text;
  if (frame >= 0) where += ", frame " + std::to_string(frame);
  throw Error(where + ": " + e.what());
}

namespace {

/// frames.csv written row by row (flushed), so a killed run keeps the frames it computed.
class FramesCsv {
 public:
  explicit FramesCsv(const std::string& path) : path_(path), f_(std::fopen(path.c_str(), "w")) {
    if (!f_) throw Error(path + ": cannot open for writing");
    put(frames_csv_header());
  }
  ~FramesCsv() {
    if (f_) std::fclose(f_);
  }
  void put(const std::string& line) {
    if (std::fputs(line.c_str(), f_) < 0 || std::fflush(f_) != 0) throw Error(path_ + ": write failed (disk full?)");
  }
  void close() {
    const int rc = std::fclose(f_);
    f_ = nullptr;
    if (rc != 0) throw Error(path_ + ": write failed (disk full?)");
  }

 private:
  std::string path_;
  std::FILE* f_;
};

}  // namespace

void register_run(CLI::App& app) {
  auto o = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand("run", "Play a scenario (default: the paper protocol) and write DIR/frames.csv");
  add_volume_options(cmd, o->source);
  cmd->add_option("--dynamics", o->dynamics, "Velocity layer: none (A) | simple (B) | viscoelastic (C); overrides --params");
  cmd->add_option("--params", o->params, "Parameter file (TOML, see `hpcm params --defaults`)");
  cmd->add_option("--scenario", o->scenario, "Scenario file (TOML) or 'paper' (default)");
  add_int_option(cmd, "--frames", o->frames, 1, 10'000'000, "Frames to run (default: the scenario's length; more frames run idle)");
  cmd->add_option("--backend", o->backend, "cpu | cuda")->capture_default_str();
  cmd->add_option("--out", o->out, "Output folder (written as OUT.incomplete, renamed to OUT when the run finishes)")->required();
  cmd->add_flag("--no-link-check", o->no_link_check, "Skip the O(N) max_link_violation measurement per frame");
  add_export_options(cmd, *o);
  cmd->callback([o] {
    // Every option and input file is checked before anything is created or simulated.
    const BackendKind bk = parse_backend(o->backend, "--backend");
    const Params p = resolve_params(*o);
    const Scenario sc = resolve_scenario(*o);
    const std::string sc_label = scenario_label(o->scenario);
    if (o->export_every > 0 && o->export_dir.empty()) throw Error("--export-every needs --export DIR");
    if (o->strict && o->no_link_check)
      throw Error("--strict judges every frame's cell determinants, which --no-link-check skips: give one of them");
    check_memory_before_load(o->source, kRunBytesPerElement);
    RunOutputs out(o->out, o->export_dir);
    RunOptions ro = *o;
    if (!o->export_dir.empty()) {
      ro.export_dir = out.export_path();
      ro.export_shown = out.export_shown();
    }

    const Volume v = load_volume(o->source);
    check_lattice_fits(v, o->source, kRunBytesPerElement);
    Simulation sim(build_model(v, p), p, bk);
    std::optional<ScenarioPlayer> player;
    try {
      player.emplace(sc, sim);
    } catch (const Error& e) {
      rethrow_in_scenario(e, sc, sc_label, -1);
    }
    const int frames = o->frames.value_or(sc.frames);
    ExportSession exporter(ro, sim);
    FramesCsv csv(out.out_path() + "/frames.csv");
    out.keep_on_failure();
    StepOptions so;
    so.link_violation = !o->no_link_check;
    so.cell_jacobian = !o->no_link_check;
    const bool progress = want_progress();
    LimitedPullTracker limited(sc);
    FoldedFrames folded;
    float worst = 0;
    try {
      for (int f = 0; f < frames; ++f) {
        FrameReport r;
        try {
          r = player->done() ? sim.step(so) : player->step(so);
        } catch (const Error& e) {
          rethrow_in_scenario(e, sc, sc_label, f);
        }
        worst = std::max(worst, r.max_link_violation);
        folded.add(r);
        csv.put(frames_csv_row(r));
        if (const auto ended = limited.after_frame(r, sim.tool_offset(), sim.requested_offset()))
          print_limited_pull(*ended, sim.model(), sc_label);
        exporter.after_frame(f, frames);
        if (progress) progress_bar("run", f + 1, frames);
      }
      if (const auto ended = limited.finish()) print_limited_pull(*ended, sim.model(), sc_label);
      csv.close();
      exporter.finish(frames);
    } catch (const Error& e) {
      throw Error(std::string(e.what()) + "\n  the frames computed so far are in " + out.out_path() + "/frames.csv");
    }
    out.commit();
    std::printf("%d frames, %lld elements, %s, dynamics %s: wrote %s/frames.csv", frames,
                static_cast<long long>(sim.model().size()), backend_name(bk), damping_mode_name(p.dynamics.mode),
                out.out_shown().c_str());
    if (so.link_violation) std::printf(" (max link violation %.3g)", worst);
    std::printf("\n");
    if (folded.any()) std::fprintf(stderr, "hpcm: warning: %s\n", folded.text().c_str());
    if (o->strict && (folded.any() || !exporter.problems().empty())) {
      std::string msg = "--strict: ";
      if (folded.any()) msg += "frames fold, " + out.out_shown() + "/frames.csv must not be trusted:\n  " + folded.text();
      if (folded.any() && !exporter.problems().empty()) msg += "\n";
      if (!exporter.problems().empty()) {
        msg += "the exports in " + out.export_shown() + " were written but must not be trusted as they are:";
        for (const std::string& p : exporter.problems()) msg += "\n  " + p;
        msg += "\n  (figures per export in " + out.export_shown() + "/export.json)";
      }
      throw Error(msg);
    }
  });
}

}  // namespace hpcm::cli
