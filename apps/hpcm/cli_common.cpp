#include "cli_common.hpp"

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "hpcm/config.hpp"
#include "int_option.hpp"
#include "memory_estimate.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::cli {

namespace {
std::vector<long long> parse_ints(const std::string& s, const std::string& option, std::size_t count, long long lo,
                                  long long hi) {
  std::vector<long long> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(parse_integer(item, option + " '" + s + "': value", lo, hi));
  if (out.size() != count || (!s.empty() && s.back() == ','))
    throw Error(option + " '" + s + "': expected " + std::to_string(count) + " comma-separated integers");
  return out;
}

/// "--downsample,-f" -> "--downsample" (the name messages use).
std::string option_label(const std::string& name) { return name.substr(0, name.find(',')); }
}  // namespace

Int3 parse_int3(const std::string& s, const std::string& option, int lo, int hi) {
  const auto v = parse_ints(s, option, 3, lo, hi);
  return {static_cast<int>(v[0]), static_cast<int>(v[1]), static_cast<int>(v[2])};
}

CLI::Option* add_int_option(CLI::App* cmd, const std::string& name, int& target, int lo, int hi, const std::string& desc) {
  const std::string label = option_label(name);
  return cmd
      ->add_option_function<std::string>(
          name, [&target, label, lo, hi](const std::string& v) { target = static_cast<int>(parse_integer(v, label, lo, hi)); },
          desc + " [" + std::to_string(lo) + ", " + std::to_string(hi) + "]" +
              (target >= lo && target <= hi ? " (default " + std::to_string(target) + ")" : ""))
      ->type_name("INT");
}

CLI::Option* add_int_option(CLI::App* cmd, const std::string& name, std::optional<int>& target, int lo, int hi,
                            const std::string& desc) {
  const std::string label = option_label(name);
  return cmd
      ->add_option_function<std::string>(
          name, [&target, label, lo, hi](const std::string& v) { target = static_cast<int>(parse_integer(v, label, lo, hi)); },
          desc + " [" + std::to_string(lo) + ", " + std::to_string(hi) + "]")
      ->type_name("INT");
}

CLI::Option* add_seed_option(CLI::App* cmd, const std::string& name, std::uint64_t& target, const std::string& desc) {
  const std::string label = option_label(name);
  return cmd
      ->add_option_function<std::string>(
          name, [&target, label](const std::string& v) { target = parse_u64(v, label); },
          desc + " [0, 2^64-1] (default " + std::to_string(target) + ")")
      ->type_name("INT");
}

void add_volume_options(CLI::App* cmd, VolumeSource& src) {
  auto* ph = cmd->add_option("--phantom", src.phantom, "Built-in synthetic phantom of size NX,NY,NZ (default " +
                                                           std::to_string(src.default_phantom.x) + "," +
                                                           std::to_string(src.default_phantom.y) + "," +
                                                           std::to_string(src.default_phantom.z) + ")");
  auto* in = cmd->add_option("--input", src.input, "CT volume (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd) or DICOM directory");
  auto* variant = cmd->add_option("--phantom-variant", src.phantom_variant,
                                  "Phantom anatomy: standard | thin-tissue | thick-fat | air-pockets | table | "
                                  "anisotropic (see docs/tuning.md)")
                       ->capture_default_str();
  ph->excludes(in);
  in->excludes(ph);
  variant->excludes(in);
  in->excludes(variant);
  add_int_option(cmd, "--downsample", src.downsample, 1, 4096, "Integer down-sampling factor per axis (block mean of HU)");
  cmd->add_option("--roi", src.roi, "Crop x0,y0,z0,x1,y1,z1 in voxels of the input (upper bounds exclusive)");
  cmd->add_option("--series", src.series, "DICOM series in a directory with several: its SeriesInstanceUID, or '#N' as listed (also for an empty UID)");
  cmd->add_option("--dicom-duplicates", src.dicom_duplicates,
                  "DICOM slices at the same position: error (default) | first (keep the lowest InstanceNumber)")
      ->check(CLI::IsMember({"error", "first"}));
  cmd->add_flag("--dicom-skip-unreadable", src.dicom_skip_unreadable,
                "Skip files of a DICOM directory that are not readable DICOM (listed as a warning; gaps stay errors)");
  add_seed_option(cmd, "--seed", src.seed, "Phantom noise seed");
}

void check_memory_before_load(const VolumeSource& src, double bytes_per_element) {
  if (!src.input.empty()) return;  // file volumes: the reader checks its own memory, the lattice is checked after
  const Int3 d = src.phantom.empty() ? src.default_phantom : parse_int3(src.phantom, "--phantom", 8, 4096);
  const std::string what = "--phantom " + std::to_string(d.x) + "," + std::to_string(d.y) + "," + std::to_string(d.z);
  // Without --roi/--downsample the phantom is the lattice; otherwise only its volume (4 bytes per
  // voxel, twice while cropping or down-sampling) exists at full size.
  const bool reduced = !src.roi.empty() || src.downsample > 1;
  check_lattice_memory(d, reduced ? 8.0 : bytes_per_element, what);
}

void check_lattice_fits(const Volume& lattice, const VolumeSource& src, double bytes_per_element) {
  const std::string what = src.input.empty() ? std::string("the phantom lattice") : src.input;
  check_lattice_memory(lattice.dims, bytes_per_element, what);
}

Volume load_volume_full(const VolumeSource& src) {
  if (!src.input.empty()) {
#if defined(HPCM_WITH_ITK)
    io::ReadOptions ro;
    ro.series_uid = src.series;
    ro.dicom_duplicates = src.dicom_duplicates == "first" ? io::DicomDuplicates::First : io::DicomDuplicates::Error;
    ro.dicom_skip_unreadable = src.dicom_skip_unreadable;
    return io::read_volume_as_stored(src.input, ro);
#else
    throw Error("--input " + src.input + ": hpcm was built without ITK, so only --phantom is available");
#endif
  }
  PhantomOptions po;
  po.dims = src.phantom.empty() ? src.default_phantom : parse_int3(src.phantom, "--phantom", 8, 4096);
  po.seed = src.seed;
  po.variant = parse_phantom_variant(src.phantom_variant, "--phantom-variant");
  return make_phantom(po);
}

namespace {
// --roi (voxels of the input as stored) and --downsample, checked against the stored volume.
Volume crop_to_roi_and_check_factor(Volume v, const VolumeSource& src, Int3* roi_lo, Int3* roi_hi) {
  if (src.downsample < 1) throw Error("--downsample " + std::to_string(src.downsample) + " is out of range: must be >= 1");
  *roi_lo = {0, 0, 0};
  *roi_hi = v.dims;
  if (!src.roi.empty()) {
    const auto r = parse_ints(src.roi, "--roi", 6, 0, 2147483647);
    *roi_lo = Int3{int(r[0]), int(r[1]), int(r[2])};
    *roi_hi = Int3{int(r[3]), int(r[4]), int(r[5])};
    v = crop(v, *roi_lo, *roi_hi);
  }
  const int mind = std::min({v.dims.x, v.dims.y, v.dims.z});
  if (src.downsample > mind)
    throw Error("--downsample " + std::to_string(src.downsample) + " is larger than the smallest volume dimension " +
                std::to_string(mind));
  return v;
}
}  // namespace

#if defined(HPCM_WITH_ITK)
io::Input load_input(const VolumeSource& src) {
  Volume stored = load_volume_full(src);
  io::InputOptions opt;
  opt.downsample = src.downsample;
  Int3 lo, hi;
  stored = crop_to_roi_and_check_factor(std::move(stored), src, &lo, &hi);
  io::Input in = io::prepare_input(std::move(stored), opt, src.input.empty() ? "phantom" : src.input);
  in.roi = {lo, hi};
  const Int3 left = in.left_out;
  if (left.x || left.y || left.z)
    std::fprintf(stderr,
                 "note: --downsample %d uses complete %dx%dx%d blocks; the last %d, %d, %d voxels of the input's axes "
                 "0, 1, 2 are not in the lattice (the deformed CT still covers them)\n",
                 src.downsample, src.downsample, src.downsample, src.downsample, left.x, left.y, left.z);
  return in;
}
#endif

Volume load_volume(const VolumeSource& src) {
#if defined(HPCM_WITH_ITK)
  return load_input(src).lattice;
#else
  // Without ITK only the phantom exists, and it is stored in LPS order already.
  Int3 lo, hi;
  const Volume v = crop_to_roi_and_check_factor(load_volume_full(src), src, &lo, &hi);
  return src.downsample > 1 ? downsample(v, src.downsample) : v;
#endif
}

Params load_params_option(const std::string& path) {
  if (path.empty()) return Params{};
  return config::load_params(path);
}

void make_output_dir(const std::string& dir, const std::string& option) {
  if (dir.empty()) throw Error(option + " must name a folder");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) throw Error(option + " " + dir + ": cannot create folder (" + ec.message() + ")");
}

void require_finite(double v, const std::string& what) {
  if (!std::isfinite(v))
    throw Error(what + " is " + (std::isnan(v) ? "NaN" : "infinite") +
                "; hpcm writes no non-finite number (check the parameters: docs/parameters.md, stability)");
}

void write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw Error(path + ": cannot open for writing");
    f << text;
    f.close();  // the last buffer is written here: a full disk shows up at close
    if (!f) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw Error(path + ": write failed (disk full?)");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error(path + ": cannot rename temporary file (" + ec.message() + ")");
}

void write_json_file(const std::string& path, const nlohmann::json& doc) {
  std::string text;
  try {
    text = doc.dump(2);
  } catch (const nlohmann::json::type_error&) {  // invalid UTF-8 in a string
    text = doc.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
    std::fprintf(stderr,
                 "hpcm: warning: %s: a text in it (such as a file name) is not valid UTF-8; it is written with U+FFFD "
                 "in place of the bytes that are not\n",
                 path.c_str());
  }
  write_text_file(path, text + "\n");
}

bool want_progress() {
  const char* ci = std::getenv("CI");
  if (ci && *ci && std::string(ci) != "0" && std::string(ci) != "false") return false;
  return isatty(fileno(stderr)) != 0;
}

void progress_bar(const std::string& label, int done, int total) {
  const int width = 40;
  const int filled = total > 0 ? width * done / total : width;
  std::fprintf(stderr, "\r%-14s [%s%s] %d/%d", label.c_str(), std::string(filled, '#').c_str(),
               std::string(width - filled, '.').c_str(), done, total);
  if (done >= total) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

}  // namespace hpcm::cli
