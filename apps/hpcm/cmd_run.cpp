// hpcm run: play a scenario (default: the paper protocol) and write per-frame metrics.
#include <cstdio>
#include <fstream>
#include <sstream>

#include "cli_common.hpp"
#include "hpcm/config.hpp"
#include "run_options.hpp"

namespace hpcm::cli {

std::string frames_csv_header() {
  std::string h = "frame,stage,grab_offset,moved_elements,active_bricks,max_link_violation,chainmail_ms,sim_total_ms";
  for (int t = 0; t < kTissueCount; ++t) h += std::string(",mean_speed_") + tissue_name(t);
  for (int t = 0; t < kTissueCount; ++t) h += std::string(",max_speed_") + tissue_name(t);
  h += ",inertia_ms,snapshot_ms,propagate_sweeps,relax_sweeps";
  h += ",requested_offset,tool_limited,restored_links,restore_violation,min_cell_jacobian,folded_cells,active_elements\n";
  return h;
}

std::string frames_csv_row(const FrameReport& r) {
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
  std::snprintf(buf, sizeof buf, ",%.6g,%d,%lld,%.6g,%.6g,%lld,%lld\n", r.requested_offset, r.tool_limited ? 1 : 0,
                static_cast<long long>(r.restored_links), r.restore_violation, r.min_cell_jacobian,
                static_cast<long long>(r.folded_cells), static_cast<long long>(r.active_elements));
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

void register_run(CLI::App& app) {
  auto o = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand("run", "Play a scenario (default: the paper protocol) and write DIR/frames.csv");
  add_volume_options(cmd, o->source);
  cmd->add_option("--dynamics", o->dynamics, "Velocity layer: none (A) | simple (B) | viscoelastic (C); overrides --params");
  cmd->add_option("--params", o->params, "Parameter file (TOML, see `hpcm params --defaults`)");
  cmd->add_option("--scenario", o->scenario, "Scenario file (TOML) or 'paper' (default)");
  cmd->add_option("--frames", o->frames, "Frames to run (default: the scenario's length; more frames run idle)");
  cmd->add_option("--backend", o->backend, "cpu | cuda")->capture_default_str();
  cmd->add_option("--out", o->out, "Output folder")->required();
  cmd->add_flag("--no-link-check", o->no_link_check, "Skip the O(N) max_link_violation measurement per frame");
  add_export_options(cmd, *o);
  cmd->callback([o] {
    if (o->frames_given() && o->frames < 1)
      throw Error("--frames " + std::to_string(o->frames) + " is out of range: must be >= 1");
    const BackendKind bk = parse_backend(o->backend, "--backend");
    const Params p = resolve_params(*o);
    const Scenario sc = resolve_scenario(*o);
    make_output_dir(o->out, "--out");
    const Volume v = load_volume(o->source);
    Simulation sim(build_model(v, p), p, bk);
    ScenarioPlayer player(sc, sim);
    const int frames = o->frames_given() ? o->frames : sc.frames;
    ExportSession exporter(*o, sim);
    std::ostringstream csv;
    csv << frames_csv_header();
    StepOptions so;
    so.link_violation = !o->no_link_check;
    so.cell_jacobian = !o->no_link_check;
    const bool progress = want_progress();
    float worst = 0;
    for (int f = 0; f < frames; ++f) {
      const FrameReport r = player.done() ? sim.step(so) : player.step(so);
      worst = std::max(worst, r.max_link_violation);
      csv << frames_csv_row(r);
      exporter.after_frame(f, frames);
      if (progress) progress_bar("run", f + 1, frames);
    }
    write_text_file(o->out + "/frames.csv", csv.str());
    exporter.finish();
    std::printf("%d frames, %lld elements, %s, dynamics %s: wrote %s/frames.csv", frames,
                static_cast<long long>(sim.model().size()), backend_name(bk), damping_mode_name(p.dynamics.mode),
                o->out.c_str());
    if (so.link_violation) std::printf(" (max link violation %.3g)", worst);
    std::printf("\n");
  });
}

}  // namespace hpcm::cli
