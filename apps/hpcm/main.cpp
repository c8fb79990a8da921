// hpcm: command-line entry point. Each subcommand lives in its own cmd_*.cpp.
#include <cstdio>
#include <exception>
#include <string>

#include "cli_common.hpp"

int main(int argc, char** argv) {
  CLI::App app{"hpcm: dynamic HP-ChainMail soft-tissue deformation of CT volumes"};
  app.require_subcommand(1);
  // The same version as the Python module's hpcm.__version__ (CMake's PROJECT_VERSION).
  app.set_version_flag("--version", std::string("hpcm ") + HPCM_VERSION, "Print the hpcm version and exit");
  hpcm::cli::register_phantom(app);
  hpcm::cli::register_run(app);
  hpcm::cli::register_experiment(app);
  hpcm::cli::register_params(app);
  hpcm::cli::register_info(app);
  hpcm::cli::register_bench(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const hpcm::Error& e) {
    std::fprintf(stderr, "hpcm: error: %s\n", e.what());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "hpcm: error: out of memory\n");
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hpcm: error: %s\n", e.what());
    return 4;
  }
  return 0;
}
