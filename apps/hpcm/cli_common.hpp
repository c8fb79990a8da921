#pragma once
// Shared pieces of the hpcm subcommands: where the volume comes from, parameter loading,
// output folders, progress.
#include <CLI/CLI.hpp>
#include <nlohmann/json_fwd.hpp>
#include <cstdint>
#include <optional>
#include <string>

#include "hpcm/hpcm.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::cli {

/// --phantom NX,NY,NZ [--phantom-variant NAME] | --input VOLUME [--downsample F] [--roi x0,y0,z0,x1,y1,z1] [--series UID] [--seed S]
/// [--dicom-duplicates error|first] [--dicom-skip-unreadable]
struct VolumeSource {
  std::string phantom;     ///< "NX,NY,NZ"
  std::string phantom_variant = "standard";
  std::string input;       ///< file or DICOM directory
  int downsample = 1;
  std::string roi;
  std::string series;
  std::string dicom_duplicates = "error";
  bool dicom_skip_unreadable = false;
  std::uint64_t seed = 1;
  Int3 default_phantom{128, 128, 75};
};
void add_volume_options(CLI::App* cmd, VolumeSource& src);
/// Loads (or generates), crops to --roi (the input's own voxel indices), down-samples in the
/// input's index order and reorients to the lattice's LPS order. Throws hpcm::Error naming the option.
Volume load_volume(const VolumeSource& src);
/// The volume as stored: the input file's own index order and geometry, not cropped.
Volume load_volume_full(const VolumeSource& src);
#if defined(HPCM_WITH_ITK)
/// load_volume with everything the exports need to come back to the input's grid.
io::Input load_input(const VolumeSource& src);
#endif

/// "NX,NY,NZ" -> Int3, each in [lo, hi]; throws naming `option`.
Int3 parse_int3(const std::string& s, const std::string& option, int lo, int hi);

/// Integer options parsed exactly (no wrap, no clamp) and range-checked while the command line
/// is parsed, before any command runs; the message names the option, value and range.
CLI::Option* add_int_option(CLI::App* cmd, const std::string& name, int& target, int lo, int hi, const std::string& desc);
/// Same, for an option that may be absent (nullopt when not given).
CLI::Option* add_int_option(CLI::App* cmd, const std::string& name, std::optional<int>& target, int lo, int hi,
                            const std::string& desc);
/// Seeds: [0, 2^64 - 1], never clamped or wrapped.
CLI::Option* add_seed_option(CLI::App* cmd, const std::string& name, std::uint64_t& target, const std::string& desc);

/// Refuses, before anything is generated or allocated, a phantom lattice that cannot fit in
/// memory at `bytes_per_element` (see memory_estimate.hpp).
void check_memory_before_load(const VolumeSource& src, double bytes_per_element);
/// Refuses a loaded lattice that cannot fit, before the model and simulation are allocated.
void check_lattice_fits(const Volume& lattice, const VolumeSource& src, double bytes_per_element);

/// --params FILE (+ --dynamics override); returns validated params.
Params load_params_option(const std::string& path);

/// Creates DIR (and parents); throws naming `option` when impossible.
void make_output_dir(const std::string& dir, const std::string& option);
/// Writes text atomically (temp file + rename).
void write_text_file(const std::string& path, const std::string& text);
/// Writes a JSON document (indented) with write_text_file. Text that is not valid UTF-8 (a
/// file name with other bytes) is written with U+FFFD in its place and a warning, never dropped.
void write_json_file(const std::string& path, const nlohmann::json& doc);
/// Throws hpcm::Error naming `what` when a value bound for an output file is NaN or infinite.
void require_finite(double v, const std::string& what);

/// True when stderr is a terminal and CI is not set.
bool want_progress();
void progress_bar(const std::string& label, int done, int total);

void register_phantom(CLI::App& app);
void register_run(CLI::App& app);
void register_experiment(CLI::App& app);
void register_params(CLI::App& app);
void register_info(CLI::App& app);
void register_bench(CLI::App& app);

}  // namespace hpcm::cli
