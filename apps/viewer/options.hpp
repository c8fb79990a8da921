#pragma once
// Command line of hpcm-viewer (CLI11). GL-free.
#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "hpcm/types.hpp"

namespace hpcm::viewer {

struct Options {
  // data
  std::string input;                 ///< volume file or DICOM directory (needs hpcm::io)
  int downsample = 1;                ///< [1, 64]
  std::optional<Int3> phantom;       ///< --phantom NX,NY,NZ (default 96,96,64 without --input)
  std::uint64_t seed = 1;
  float noise_hu = 12.0f;
  // simulation
  std::string params;                ///< TOML parameter file (needs hpcm::config)
  std::string scenario;              ///< TOML file, "paper" or "none"
  std::string backend = "cpu";
  std::string mode;                  ///< damping override: none|simple|viscoelastic|A|B|C
  float radius = 0;                  ///< grab radius override (> 0), 0 = from params
  int frames = -1;                   ///< frames to play (-1: scenario length)
  double sim_rate = 0;               ///< simulation frames per second, 0 = as fast as it can
  // scripted output
  std::string screenshot;            ///< PNG written after the last frame, then exit
  std::string record;                ///< directory: one PNG per frame, then exit
  std::string report;                ///< text file with view geometry (for tests and figures)
  double bench_drag = 0;             ///< seconds of scripted dragging, measuring both rates (0: off)
  int stall_frame = 0;               ///< test aid: hold this simulation frame until the display drew 30 frames
  // display
  int width = 1280, height = 800;
  int max_fps = 60;                  ///< display frames per second at most, 0 = no limit
  std::string layout = "all";        ///< all|axial|coronal|sagittal
  std::string colour = "hu";         ///< hu|tissue
  std::string overlay = "none";      ///< none|speed|displacement
  float overlay_max = 0;             ///< 0: automatic range
  float level = 40, window = 400;    ///< HU window
  std::array<int, 3> slices{-1, -1, -1};  ///< x (sagittal), y (coronal), z (axial); -1 auto
  bool hide_panel = false;
  bool wire = false;
  bool hide_tool = false;            ///< do not draw the grab tool (figures, tests)
  bool paused = false;

  bool bench() const { return bench_drag > 0; }
  bool scripted() const { return !screenshot.empty() || !record.empty() || bench(); }
};

/// Parses the command line. Returns -1 to continue, or the exit code (0 after --help,
/// non-zero after a usage error, with the message already printed).
int parse_options(int argc, char** argv, Options& o);

/// "A,B,C" -> Int3, each an exact integer in [lo, hi]; throws hpcm::Error naming `what`.
Int3 parse_int3(const std::string& s, const std::string& what, int lo = -2147483647 - 1, int hi = 2147483647);

}  // namespace hpcm::viewer
