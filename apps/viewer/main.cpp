// hpcm-viewer: interactive viewer of the dynamic HP-ChainMail simulation (docs/viewer.md).
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>

#include "hpcm/hpcm.hpp"
#include "memory_estimate.hpp"
#include "options.hpp"
#include "viewer.hpp"

#ifdef HPCM_VIEWER_WITH_IO
#include "hpcm/io.hpp"
#endif
#ifdef HPCM_VIEWER_WITH_CONFIG
#include "hpcm/config.hpp"
#endif

namespace fs = std::filesystem;
using namespace hpcm;
using namespace hpcm::viewer;

namespace {

void require_file(const std::string& path, const char* what) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(std::string(what) + ": file not found: " + path);
}

void require_parent_dir(const std::string& path, const char* what) {
  const fs::path parent = fs::absolute(fs::path(path)).parent_path();
  std::error_code ec;
  if (!fs::is_directory(parent, ec)) throw Error(std::string(what) + ": directory does not exist: " + parent.string());
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const int rc = parse_options(argc, argv, o); rc >= 0) return rc;
  try {
    // 1. Cheap checks and small files first, so mistakes are reported before any window.
    Session s;
    if (!o.input.empty()) {
      require_file(o.input, "--input");
#ifndef HPCM_VIEWER_WITH_IO
      throw Error("--input " + o.input + ": this hpcm-viewer was built without volume IO (ITK); use --phantom");
#endif
    }
    if (!o.params.empty()) {
      require_file(o.params, "--params");
#ifdef HPCM_VIEWER_WITH_CONFIG
      s.params = config::load_params(o.params);
#else
      throw Error("--params " + o.params + ": this hpcm-viewer was built without parameter files (toml++)");
#endif
    }
    if (!o.mode.empty()) s.params.dynamics.mode = parse_damping_mode(o.mode, "--mode");
    if (o.radius > 0) s.params.solver.grab_radius = o.radius;
    s.params.validate();
    s.backend = parse_backend(o.backend, "--backend");
    if (o.scenario == "paper") {
      s.scenario = Scenario::paper_protocol();
    } else if (o.scenario == "none") {
      Scenario none;
      none.name = "none";
      none.frames = o.frames > 0 ? o.frames : Scenario::paper_protocol().frames;
      s.scenario = none;
    } else if (!o.scenario.empty()) {
      require_file(o.scenario, "--scenario");
#ifdef HPCM_VIEWER_WITH_CONFIG
      s.scenario = config::load_scenario(o.scenario);
#else
      throw Error("--scenario " + o.scenario +
                  ": this hpcm-viewer was built without scenario files (toml++); use --scenario paper");
#endif
    }
    if (!o.screenshot.empty()) require_parent_dir(o.screenshot, "--screenshot");
    if (!o.report.empty()) require_parent_dir(o.report, "--report");
    if (!o.record.empty()) require_parent_dir(o.record, "--record");

    // 2. A display is needed for the OpenGL context (also in scripted use: run under xvfb-run).
    if (!display_available()) {
      std::fprintf(stderr, "%s\n", kNoDisplayMessage);
      return 2;
    }

    // 3. The lattice.
    Volume v;
    if (!o.input.empty()) {
#ifdef HPCM_VIEWER_WITH_IO
      v = io::read_volume(o.input);
      if (o.downsample > 1) v = downsample(v, o.downsample);
      s.source = o.input + (o.downsample > 1 ? " (f=" + std::to_string(o.downsample) + ")" : "");
#endif
    } else {
      PhantomOptions po;
      po.dims = o.phantom.value_or(Int3{96, 96, 64});
      cli::check_lattice_memory(po.dims, cli::kViewerBytesPerElement, "--phantom");
      po.seed = o.seed;
      po.noise_hu = o.noise_hu;
      v = make_phantom(po);
      s.source = "phantom " + std::to_string(po.dims.x) + "x" + std::to_string(po.dims.y) + "x" +
                 std::to_string(po.dims.z) + " (seed " + std::to_string(po.seed) + ")";
    }
    cli::check_lattice_memory(v.dims, cli::kViewerBytesPerElement, o.input.empty() ? "--phantom" : o.input);
    s.model = build_model(v, s.params);
    if (s.scenario && !(s.scenario->name == "none" && s.scenario->grabs.empty())) {
      try {
        s.scenario->in_lattice_units(s.model).validate(s.model);
      } catch (const Error& e) {
        throw Error("--scenario " + o.scenario + ": " + e.what());  // name the file, not only the grab
      }
    }

    Viewer viewer(o, std::move(s));
    return viewer.run();
  } catch (const Error& e) {
    std::fprintf(stderr, "hpcm-viewer: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hpcm-viewer: unexpected error: %s\n", e.what());
    return 1;
  }
}
