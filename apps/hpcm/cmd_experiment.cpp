// hpcm experiment: conditions A/B/C of the paper on identical input, the tables, the SPEC §8
// checks, figures and a Markdown report.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "cli_common.hpp"
#include "hpcm/config.hpp"
#include "hpcm/experiment.hpp"
#include "hpcm/param_table.hpp"
#include "memory_estimate.hpp"
#include "output_dir.hpp"
#include "pull_limit_notes.hpp"
#include "run_options.hpp"
#include "spawn.hpp"

namespace hpcm::cli {

namespace {

std::string machine_description() {
  std::ifstream f("/proc/cpuinfo");
  std::string line, model = "unknown CPU";
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  return model + ", " + std::to_string(std::thread::hardware_concurrency()) + " hardware threads";
}

nlohmann::json per_tissue_json(const PerTissue& v) {
  nlohmann::json j;
  for (int t = 0; t < kTissueCount; ++t) j[tissue_name(t)] = v[t];
  return j;
}

// SPEC §3: which elements the statistics count, and which were left out and why.
nlohmann::json body_json(const Model& m) {
  const BodySummary& b = m.body;
  const char* search = b.search == BodySummary::Search::Found ? "found"
                       : b.search == BodySummary::Search::NoBody ? "none" : "not searched";
  nlohmann::json j = {{"search", search}, {"method", b.method}, {"counted_elements", b.body},
                      {"left_out", {{"outside_air", b.outside_air}, {"outside_objects", b.outside_objects}}},
                      {"why", b.describe()}, {"counted_class_count", nlohmann::json::object()}};
  for (int t = 0; t < kTissueCount; ++t) j["counted_class_count"][tissue_name(t)] = m.counted_class_count[t];
  return j;
}

// Every parameter, written from the parameter table (the one declaration of each key), so the
// summary records every setting a run used: {section: {name: value}}, material points as rows.
nlohmann::json params_json(const Params& p) {
  Params q = p;  // the table's accessors take a mutable Params
  nlohmann::json j;
  for (const ParamSpec& s : param_table()) {
    if (s.type == ParamType::PointField) continue;  // a column of material.points, written as rows
    nlohmann::json& v = j[s.section()][s.name()];
    switch (s.type) {
      case ParamType::Real: v = s.real(q); break;
      case ParamType::Integer: v = s.integer(q); break;
      case ParamType::Flag: v = s.flag(q); break;
      case ParamType::Choice: v = s.choice_name(q); break;
      case ParamType::PerClass: v = per_tissue_json(s.per_class(q)); break;
      case ParamType::Points:
        v = nlohmann::json::array();
        for (const MaterialPoint& pt : s.points(q)) v.push_back({{"hu", pt.hu}, {"tau", pt.tau}, {"w", pt.w}});
        break;
      case ParamType::PointField: break;
    }
  }
  return j;
}

std::string find_report_script() {
  const char* env = std::getenv("HPCM_REPORT_SCRIPT");
  if (env && *env) return env;
  for (const std::string& p : {std::string(HPCM_SOURCE_DIR) + "/scripts/hpcm_report.py", std::string("/usr/local/share/hpcm/hpcm_report.py"),
                               std::string("/usr/share/hpcm/hpcm_report.py")})
    if (std::filesystem::exists(p)) return p;
  return {};
}

/// Each limited stretch once, naming the conditions it occurred in (the input is the same for
/// A, B and C, so usually all three).
void print_limited_pulls(const ExperimentResult& r, const Model& m, const std::string& label) {
  std::vector<std::pair<std::string, std::string>> notes;  // text, conditions
  for (const auto& c : r.conditions)
    for (const LimitedPull& lp : c.limited_pulls) {
      const std::string text = limited_pull_text(lp, m, label);
      auto it = std::find_if(notes.begin(), notes.end(), [&](const auto& n) { return n.first == text; });
      if (it == notes.end()) notes.emplace_back(text, c.label);
      else it->second += ", " + c.label;
    }
  for (const auto& [text, conditions] : notes)
    std::fprintf(stderr, "hpcm: note: condition%s %s: %s\n", conditions.size() > 1 ? "s" : "", conditions.c_str(),
                 text.c_str());
}

}  // namespace

void register_experiment(CLI::App& app) {
  struct Opts {
    VolumeSource source;
    std::string params, scenario, out, backend = "cpu";
    int settle = 2000;
    bool no_report = false;
    bool strict = false;
  };
  auto o = std::make_shared<Opts>();
  o->source.default_phantom = {128, 128, 75};
  auto* cmd = app.add_subcommand("experiment", "Run conditions A/B/C of the paper protocol and write tables, checks, figures, report");
  add_volume_options(cmd, o->source);
  cmd->add_option("--params", o->params, "Parameter file (TOML)");
  cmd->add_option("--scenario", o->scenario, "Scenario file (TOML) instead of the paper protocol");
  add_int_option(cmd, "--settle-frames", o->settle, 1, 10'000'000, "Idle frames after the scenario for the settling check");
  cmd->add_option("--backend", o->backend, "cpu | cuda")->capture_default_str();
  cmd->add_option("--out", o->out, "Output folder (written as OUT.incomplete, renamed to OUT when it finishes)")->required();
  cmd->add_flag("--no-report", o->no_report, "Write the CSV/JSON files only (no figures, no report.md)");
  cmd->add_flag("--strict", o->strict,
                "Exit with an error (after writing every file) when a frame of any condition folds (a cell corner "
                "determinant <= 0 at frame end)");
  cmd->callback([o] {
    const Params p = load_params_option(o->params);
    ExperimentOptions eo;
    eo.backend = parse_backend(o->backend, "--backend");
    eo.settle_frames = o->settle;
    if (!o->scenario.empty() && o->scenario != "paper") eo.scenario = config::load_scenario(o->scenario);
    const std::string sc_label = scenario_label(o->scenario);
    std::string script;
    if (!o->no_report) {
      script = find_report_script();
      if (script.empty()) throw Error("report script hpcm_report.py not found (set HPCM_REPORT_SCRIPT or use --no-report)");
    }
    check_memory_before_load(o->source, kExperimentBytesPerElement);
    StagedDir out(o->out, "--out");
    const std::string dir = out.path();
    const Volume v = load_volume(o->source);
    check_lattice_fits(v, o->source, kExperimentBytesPerElement);
    const Model m = build_model(v, p);
    std::fprintf(stderr, "note: %s\n", m.body.describe().c_str());
    if (want_progress())
      eo.progress = [](int c, int done, int total) {
        if (done % 10 == 0 || done == total) progress_bar(std::string("condition ") + char('A' + c), done, total);
      };
    ExperimentResult r;
    try {
      eo.scenario.validate(m);
      r = run_experiment(m, p, eo);
    } catch (const Error& e) {
      rethrow_in_scenario(e, eo.scenario, sc_label, -1);
    }

    std::ostringstream curves, t2, t3, activity;
    curves << "condition,frame_after_release,tissue,mean_speed,max_speed\n";
    activity << "condition,frame,stage,active_bricks,active_elements,moved_elements,sim_total_ms,max_link_violation,"
                "min_cell_jacobian,tool_limited\n";
    t2 << "condition,tissue,initial,peak,auc\n";
    t3 << "condition,chainmail_ms,inertia_ms,snapshot_ms,sim_total_ms\n";
    nlohmann::json js;
    js["lattice"] = {{"dims", {m.dims.x, m.dims.y, m.dims.z}}, {"elements", m.size()},
                     {"source", o->source.input.empty() ? "phantom " + (o->source.phantom.empty() ? std::string("128,128,75") : o->source.phantom) +
                                                              (o->source.phantom_variant == "standard" ? "" : " " + o->source.phantom_variant)
                                                        : o->source.input},
                     {"downsample", o->source.downsample}, {"class_count", {}}};
    for (int t = 0; t < kTissueCount; ++t) js["lattice"]["class_count"][tissue_name(t)] = m.class_count[t];
    js["body"] = body_json(m);
    js["backend"] = backend_name(eo.backend);
    js["machine"] = machine_description();
    js["scenario"] = {{"name", eo.scenario.name}, {"frames", eo.scenario.frames}, {"release_frame", r.release_frame},
                      {"recorded_frames", r.recorded_frames}, {"settle_frames", eo.settle_frames}, {"grab_centre", r.grab_centre},
                      {"far_field_distance", r.far_field_distance}};
    const Int3 gc = m.coords(r.grab_centre);
    js["scenario"]["grab_centre_xyz"] = {gc.x, gc.y, gc.z};
    js["params"] = params_json(p);
    char buf[256];
    for (const auto& c : r.conditions) {
      const std::string cond = "condition " + c.label;
      for (int t = 0; t < kTissueCount; ++t) {
        require_finite(c.initial[t], cond + " initial speed of " + tissue_name(t));
        require_finite(c.peak[t], cond + " peak speed of " + tissue_name(t));
        require_finite(c.auc[t], cond + " AUC of " + tissue_name(t));
      }
      require_finite(c.settle_max_speed, cond + " settle_max_speed");
      for (int f = r.release_frame; f < static_cast<int>(c.frames.size()); ++f)
        for (int t = 0; t < kTissueCount; ++t) {
          require_finite(c.frames[f].mean_speed[t], cond + " frame " + std::to_string(f) + " mean speed");
          require_finite(c.frames[f].max_speed[t], cond + " frame " + std::to_string(f) + " max speed");
          std::snprintf(buf, sizeof buf, "%s,%d,%s,%.9g,%.9g\n", c.label.c_str(), f - r.release_frame, tissue_name(t),
                        c.frames[f].mean_speed[t], c.frames[f].max_speed[t]);
          curves << buf;
        }
      // Work per frame: how much of the lattice was active (bricks with any work), every frame
      // of the protocol, frame numbers relative to the release.
      for (std::size_t f = 0; f < c.frames.size(); ++f) {
        const FrameReport& fr = c.frames[f];
        std::snprintf(buf, sizeof buf, "%s,%d,%s,%lld,%lld,%lld,%.6f,%.6g,%.6g,%d\n", c.label.c_str(),
                      static_cast<int>(f) - r.release_frame, fr.deform ? "deform" : "idle",
                      static_cast<long long>(fr.active_bricks), static_cast<long long>(fr.active_elements),
                      static_cast<long long>(fr.moved_elements), fr.sim_total_ms, fr.max_link_violation,
                      fr.min_cell_jacobian, fr.tool_limited ? 1 : 0);
        activity << buf;
      }
      auto& jc = js["conditions"][c.label];
      jc["mode"] = damping_mode_name(c.mode);
      for (int t = 0; t < kTissueCount; ++t) {
        std::snprintf(buf, sizeof buf, "%s,%s,%.9g,%.9g,%.9g\n", c.label.c_str(), tissue_name(t), c.initial[t], c.peak[t], c.auc[t]);
        t2 << buf;
        jc["tissues"][tissue_name(t)] = {{"initial", c.initial[t]}, {"peak", c.peak[t]}, {"auc", c.auc[t]}};
      }
      std::snprintf(buf, sizeof buf, "%s,%.6f,%.6f,%.6f,%.6f\n", c.label.c_str(), c.chainmail_ms, c.inertia_ms, c.snapshot_ms,
                    c.sim_total_ms);
      t3 << buf;
      jc["timing_ms"] = {{"chainmail", c.chainmail_ms}, {"inertia", c.inertia_ms}, {"snapshot", c.snapshot_ms}, {"sim_total", c.sim_total_ms}};
      jc["settle_max_speed"] = c.settle_max_speed;
      // SPEC §8.8: share of each class's AUC after release carried by the far field (null: the
      // class did not move).
      auto& ff = jc["far_field_share"];
      ff = nlohmann::json::object();
      for (int t = 0; t < kTissueCount; ++t) {
        const double share = far_field_share(c.far_speed_sum, c.total_speed_sum, t);
        ff[tissue_name(t)] = share >= 0 ? nlohmann::json(share) : nlohmann::json(nullptr);
      }
      jc["limited_pulls"] = nlohmann::json::array();
      for (const LimitedPull& lp : c.limited_pulls) jc["limited_pulls"].push_back(limited_pull_json(lp, m));
      nlohmann::json track = nlohmann::json::array();
      for (std::size_t f = 0; f < c.centre_displacement.size(); ++f) {
        const Vec3 d = c.centre_displacement[f];
        for (float x : {d.x, d.y, d.z}) require_finite(x, cond + " grab centre displacement");
        track.push_back({d.x, d.y, d.z});
      }
      jc["grab_centre_displacement"] = track;
      // With the displacement, the velocity state tells what the layer fed: the ChainMail
      // correction of frame t is u(t) - beta rho V(t) - u(t - 1) where nothing clamped.
      nlohmann::json velocity = nlohmann::json::array();
      for (const Vec3& v : c.centre_velocity) {
        for (float x : {v.x, v.y, v.z}) require_finite(x, cond + " grab centre velocity");
        velocity.push_back({v.x, v.y, v.z});
      }
      jc["grab_centre_velocity"] = velocity;
    }
    // "holds" (true only when held) stays for older readers; "status" says held, failed or
    // not_applicable, the last with its reason. A ratio over 0 (+inf) is written as null.
    for (const auto& ch : r.checks) {
      auto& jc = js["checks"][ch.name];
      jc = {{"status", check_status_name(ch.status)}, {"holds", ch.holds()}, {"threshold", ch.threshold},
            {"spec", ch.spec}, {"description", ch.description}};
      jc["value"] = std::isfinite(ch.value) ? nlohmann::json(ch.value) : nlohmann::json(nullptr);
      if (!ch.applicable()) jc["reason"] = ch.reason;
    }
    js["check_counts"] = {{"held", r.count(CheckStatus::Held)}, {"failed", r.count(CheckStatus::Failed)},
                          {"not_applicable", r.count(CheckStatus::NotApplicable)}};
    js["all_hold"] = r.all_hold();
    write_text_file(dir + "/curves.csv", curves.str());
    write_text_file(dir + "/table2.csv", t2.str());
    write_text_file(dir + "/table3.csv", t3.str());
    write_text_file(dir + "/activity.csv", activity.str());
    write_json_file(dir + "/summary.json", js);
    out.keep_on_failure();
    if (!o->no_report) {
      // An argument vector, never a shell: no character of the paths can run a command.
      const std::vector<std::string> argv = {"/usr/bin/python3", script, "--", dir};
      const SpawnResult rc = run_program(argv, true);
      if (!rc.exited || rc.status != 0)
        throw Error("report script failed (" + describe_command(argv) + ": " +
                    (rc.exited ? "exit status " : "signal ") + std::to_string(rc.status) +
                    "); the CSV and JSON files are in " + dir);
    }
    out.commit();
    print_limited_pulls(r, m, sc_label);
    std::vector<std::string> folds;
    for (const auto& c : r.conditions)
      if (c.folded.any()) folds.push_back("condition " + c.label + ": " + c.folded.text());
    for (const std::string& f : folds) std::fprintf(stderr, "hpcm: warning: %s\n", f.c_str());
    std::printf("experiment: %lld elements, checks: %d held, %d failed, %d not applicable (of %zu); wrote "
                "%s/{curves.csv,table2.csv,table3.csv,activity.csv,summary.json%s}\n",
                static_cast<long long>(m.size()), r.count(CheckStatus::Held), r.count(CheckStatus::Failed),
                r.count(CheckStatus::NotApplicable), r.checks.size(), out.final_path().c_str(),
                o->no_report ? "" : ",figure3.png,figure4.png,figure5.png,report.md");
    for (const auto& ch : r.checks)
      if (ch.failed())
        std::printf("  failed: %s: value %.6g, threshold %.6g (%s)\n", ch.name.c_str(), ch.value, ch.threshold,
                    ch.description.c_str());
    if (o->strict && !folds.empty()) {
      std::string msg = "--strict: frames fold, the results in " + out.final_path() + " must not be trusted:";
      for (const std::string& f : folds) msg += "\n  " + f;
      throw Error(msg);
    }
  });
}

}  // namespace hpcm::cli
