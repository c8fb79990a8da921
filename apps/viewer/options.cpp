#include "options.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <vector>

#include "int_option.hpp"

namespace hpcm::viewer {

Int3 parse_int3(const std::string& s, const std::string& what, int lo, int hi) {
  std::vector<std::string> items;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) items.push_back(item);
  if (items.size() != 3 || s.empty() || s.back() == ',')
    throw Error(what + ": expected three integers NX,NY,NZ, got '" + s + "'");
  int v[3];
  for (int i = 0; i < 3; ++i) v[i] = static_cast<int>(cli::parse_integer(items[i], what + " '" + s + "': value", lo, hi));
  return {v[0], v[1], v[2]};
}

namespace {
// CLI::Range lets "nan" through (every comparison with NaN is false) and "1e39" overflows the
// float it is stored in: only finite numbers in [lo, hi] ((lo, hi] when lo_open) pass.
CLI::Validator finite_range(double lo, double hi, bool lo_open = false) {
  std::ostringstream range;
  range << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
  const std::string text = range.str();
  return CLI::Validator(
      [lo, hi, lo_open, text](std::string& s) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        const bool number = end != s.c_str() && *end == '\0';
        if (!number || !std::isfinite(v)) return "value " + s + " is not a finite number; valid: " + text;
        if ((lo_open ? !(v > lo) : !(v >= lo)) || !(v <= hi)) return "value " + s + " is out of range " + text;
        return {};
      },
      "FLOAT in " + text);
}
}  // namespace

int parse_options(int argc, char** argv, Options& o) {
  CLI::App app{
      "hpcm-viewer: interactive dynamic HP-ChainMail soft-tissue simulation on a CT volume or the "
      "built-in phantom.\nControls: left-drag on a slice grabs and pulls tissue, right/middle-drag pans, "
      "wheel zooms; space run/pause, n one frame, r reset, s screenshot, 1/2/3 damping A/B/C.\n"
      "Scripted use: --scenario FILE --frames N --screenshot OUT.png (or --record DIR) plays without a "
      "mouse, writes PNGs and exits.",
      "hpcm-viewer"};
  std::string phantom, size, slices;
  auto* in = app.add_option("--input,-i", o.input, "CT volume (NIfTI, NRRD, MetaImage) or DICOM series directory");
  app.add_option("--downsample,-f", o.downsample, "Integer down-sampling factor of --input (block mean)")
      ->check(CLI::Range(1, 64));
  auto* ph = app.add_option("--phantom", phantom, "Built-in phantom of NX,NY,NZ elements (default 96,96,64)");
  in->excludes(ph);
  std::string seed;
  app.add_option("--seed", seed, "Phantom noise seed, [0, 2^64-1]");
  app.add_option("--noise", o.noise_hu, "Phantom noise standard deviation in HU, [0, 200]")->check(CLI::Range(0.0, 200.0));
  app.add_option("--params,-p", o.params, "TOML parameter file (see hpcm params --defaults)");
  app.add_option("--scenario", o.scenario, "Scenario: TOML file, 'paper' (the paper's protocol: pull the skin 6 cells anterior over 20 frames, hold 10, release, 120 frames) or 'none'");
  app.add_option("--backend", o.backend, "cpu or cuda");
  app.add_option("--mode", o.mode, "Damping mode override: none|simple|viscoelastic (or A|B|C)");
  app.add_option("--radius", o.radius, "Grab radius override in lattice units, (0, 64]")->check(CLI::Range(0.0, 64.0));
  app.add_option("--frames,-n", o.frames, "Frames to play (default: the scenario's length)")->check(CLI::Range(0, 1000000));
  app.add_option("--sim-rate", o.sim_rate,
                 "Simulation frames per second, [0, 1000]; 0 (default) steps frames as fast as it can")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--max-fps", o.max_fps, "Display frames per second at most, [0, 1000]; 0 = no limit (default 60)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--screenshot,-o", o.screenshot, "Write a PNG of the window after the last frame and exit");
  app.add_option("--record", o.record, "Write one PNG per frame into this directory and exit");
  app.add_option("--report", o.report, "Write the view geometry (pixel of the grab point per view) to this text file");
  auto* bench = app.add_option("--bench-drag", o.bench_drag,
                 "Benchmark: drag the grab tool for this many seconds (simulation free-running), print display "
                 "and simulation frame rates and exit, (0, 3600]")
      ->check(CLI::Range(0.001, 3600.0));
  auto* stall = app.add_option("--stall-frame", o.stall_frame,
                               "Test aid (scripted runs): hold simulation frame K until the display has drawn 30 "
                               "more frames, and report it; shows that the display does not wait for the simulation")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--size", size, "Window size WxH in pixels (default 1280x800)");
  app.add_option("--layout", o.layout, "all | axial | coronal | sagittal")
      ->check(CLI::IsMember({"all", "axial", "coronal", "sagittal"}));
  app.add_option("--colour,--color", o.colour, "Base colouring: hu (HU window) or tissue")
      ->check(CLI::IsMember({"hu", "tissue"}));
  app.add_option("--overlay", o.overlay, "Overlay: none | speed | displacement")
      ->check(CLI::IsMember({"none", "speed", "displacement"}));
  app.add_option("--overlay-max", o.overlay_max, "Top of the overlay colour map in lattice units (0: automatic)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--level", o.level, "HU window level, [-32768, 32767] (the 16-bit CT range)")
      ->check(finite_range(-32768.0, 32767.0));
  app.add_option("--window", o.window, "HU window width, (0, 65536]")->check(finite_range(0.0, 65536.0, true));
  app.add_option("--slices", slices, "Slice positions X,Y,Z (sagittal x, coronal y, axial z; -1 = automatic)");
  app.add_flag("--hide-panel", o.hide_panel, "Hide the control panel (views fill the window)");
  app.add_flag("--wire", o.wire, "Draw the mesh edges");
  app.add_flag("--hide-tool", o.hide_tool, "Do not draw the grab tool");
  app.add_flag("--paused", o.paused, "Start paused (interactive use)");
  try {
    app.parse(argc, argv);
    if (o.bench() && (!o.record.empty() || !o.scenario.empty() || o.frames >= 0))
      throw CLI::ValidationError("--bench-drag", "drags its own tool: it cannot be combined with --record, --scenario or --frames");
    if (stall->count() > 0 && !o.scripted())
      throw CLI::ValidationError("--stall-frame", "needs a scripted run (--screenshot, --record or --bench-drag)");
    (void)bench;
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc;
  }
  try {
    if (!seed.empty()) o.seed = cli::parse_u64(seed, "--seed");
    if (!phantom.empty()) o.phantom = parse_int3(phantom, "--phantom", 8, 4096);
    if (!slices.empty()) {
      const Int3 s = parse_int3(slices, "--slices", -1, 1 << 20);
      o.slices = {s.x, s.y, s.z};
    }
    if (!size.empty()) {
      const auto x = size.find('x');
      if (x == std::string::npos)
        throw Error("--size: expected WxH with 320 <= W <= 16384 and 240 <= H <= 16384, got '" + size + "'");
      o.width = static_cast<int>(cli::parse_integer(size.substr(0, x), "--size width", 320, 16384));
      o.height = static_cast<int>(cli::parse_integer(size.substr(x + 1), "--size height", 240, 16384));
    }
  } catch (const Error& e) {
    std::cerr << "hpcm-viewer: " << e.what() << "\n";
    return 2;
  }
  return -1;
}

}  // namespace hpcm::viewer
