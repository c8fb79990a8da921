// hpcm params: print the default parameter file or the parameter tables of the docs, check parameter/scenario files, print the
// paper-protocol scenario file.
#include <cstdio>
#include <memory>

#include "cli_common.hpp"
#include "hpcm/config.hpp"
#include "hpcm/param_table.hpp"

namespace hpcm::cli {

namespace {
struct ParamsOptions {
  bool defaults = false;
  bool markdown = false;
  std::string check;
  std::string check_scenario;
  bool scenario_paper = false;
  bool print = false;
};

// Whether any offset or radius is in millimetres (their lattice range needs the input's spacing).
bool uses_mm(const Scenario& s) {
  for (const GrabAction& g : s.grabs) {
    if (g.radius_units == Units::mm) return true;
    for (const Keyframe& kf : g.path)
      if (kf.units == Units::mm) return true;
  }
  return false;
}
}  // namespace

void register_params(CLI::App& app) {
  auto opt = std::make_shared<ParamsOptions>();
  CLI::App* cmd = app.add_subcommand("params", "Parameter and scenario files: defaults, checks, paper protocol");
  cmd->add_flag("--defaults", opt->defaults, "Print a complete, commented parameter file with every default");
  cmd->add_flag("--markdown", opt->markdown,
                "Print the parameter tables of docs/parameters.md (key, default, range, unit, meaning)");
  cmd->add_option("--check", opt->check, "Validate a parameter file (exit 2 with the reason when invalid)");
  cmd->add_option("--check-scenario", opt->check_scenario,
                  "Validate a scenario file (syntax and values; grab positions and millimetre offsets and radii are checked "
                  "against the lattice at run time)");
  cmd->add_flag("--print", opt->print, "With --check / --check-scenario: print the full effective file");
  cmd->add_flag("--scenario-paper", opt->scenario_paper, "Print the paper-protocol scenario file (SPEC 7)");
  cmd->callback([opt]() {
    const int n = int(opt->defaults) + int(opt->markdown) + int(!opt->check.empty()) + int(!opt->check_scenario.empty()) + int(opt->scenario_paper);
    if (n != 1)
      throw CLI::ValidationError("params", "give exactly one of --defaults, --markdown, --check FILE, --check-scenario FILE, --scenario-paper");
    if (opt->print && opt->check.empty() && opt->check_scenario.empty())
      throw CLI::ValidationError("--print", "only valid with --check or --check-scenario");
    if (opt->defaults) {
      std::fputs(config::default_params_toml().c_str(), stdout);
    } else if (opt->markdown) {
      std::fputs(param_table_markdown().c_str(), stdout);
    } else if (!opt->check.empty()) {
      const Params p = config::load_params(opt->check);
      if (opt->print)
        std::fputs(config::params_to_toml(p).c_str(), stdout);
      else
        std::printf("%s: ok (dynamics.mode = %s)\n", opt->check.c_str(), damping_mode_name(p.dynamics.mode));
    } else if (!opt->check_scenario.empty()) {
      const Scenario s = config::load_scenario(opt->check_scenario);
      if (opt->print)
        std::fputs(config::scenario_to_toml(s).c_str(), stdout);
      else
        std::printf("%s: ok (scenario '%s', %d frames, %zu grab%s)%s\n", opt->check_scenario.c_str(), s.name.c_str(),
                    s.frames, s.grabs.size(), s.grabs.size() == 1 ? "" : "s",
                    uses_mm(s) ? "; millimetres are checked against the lattice spacing when the scenario is played" : "");
    } else {
      std::fputs("# The paper protocol (SPEC 7), expanded. A file holding only `paper = true` (or a [paper]\n"
                 "# table with distance, pull, hold, record) is the same; edit this one to vary it.\n",
                 stdout);
      std::fputs(config::scenario_to_toml(Scenario::paper_protocol()).c_str(), stdout);
    }
  });
}

}  // namespace hpcm::cli
