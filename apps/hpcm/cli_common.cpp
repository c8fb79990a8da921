#include "cli_common.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "hpcm/config.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::cli {

namespace {
std::vector<long long> parse_ints(const std::string& s, const std::string& option, std::size_t count) {
  std::vector<long long> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      const long long v = std::stoll(item, &used);
      if (used != item.size()) throw std::invalid_argument(item);
      out.push_back(v);
    } catch (const std::exception&) {
      throw Error(option + " '" + s + "': '" + item + "' is not an integer");
    }
  }
  if (out.size() != count)
    throw Error(option + " '" + s + "': expected " + std::to_string(count) + " comma-separated integers");
  return out;
}
}  // namespace

Int3 parse_int3(const std::string& s, const std::string& option, int lo, int hi) {
  const auto v = parse_ints(s, option, 3);
  for (long long x : v)
    if (x < lo || x > hi)
      throw Error(option + " '" + s + "': " + std::to_string(x) + " is out of range [" + std::to_string(lo) + ", " +
                  std::to_string(hi) + "]");
  return {static_cast<int>(v[0]), static_cast<int>(v[1]), static_cast<int>(v[2])};
}

void add_volume_options(CLI::App* cmd, VolumeSource& src) {
  auto* ph = cmd->add_option("--phantom", src.phantom, "Built-in synthetic phantom of size NX,NY,NZ (default " +
                                                           std::to_string(src.default_phantom.x) + "," +
                                                           std::to_string(src.default_phantom.y) + "," +
                                                           std::to_string(src.default_phantom.z) + ")");
  auto* in = cmd->add_option("--input", src.input, "CT volume (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd) or DICOM directory");
  ph->excludes(in);
  in->excludes(ph);
  cmd->add_option("--downsample", src.downsample, "Integer down-sampling factor per axis (block mean of HU), >= 1");
  cmd->add_option("--roi", src.roi, "Crop x0,y0,z0,x1,y1,z1 in voxels of the input (upper bounds exclusive)");
  cmd->add_option("--series", src.series, "DICOM series instance UID (directories with several series)");
  cmd->add_option("--seed", src.seed, "Phantom noise seed");
}

Volume load_volume_full(const VolumeSource& src) {
  if (!src.input.empty()) {
#if defined(HPCM_WITH_ITK)
    io::ReadOptions ro;
    ro.series_uid = src.series;
    return io::read_volume_as_stored(src.input, ro);
#else
    throw Error("--input " + src.input + ": hpcm was built without ITK, so only --phantom is available");
#endif
  }
  PhantomOptions po;
  po.dims = src.phantom.empty() ? src.default_phantom : parse_int3(src.phantom, "--phantom", 8, 4096);
  po.seed = src.seed;
  return make_phantom(po);
}

namespace {
// --roi (voxels of the input as stored) and --downsample, checked against the stored volume.
Volume crop_to_roi_and_check_factor(Volume v, const VolumeSource& src, Int3* roi_lo, Int3* roi_hi) {
  if (src.downsample < 1) throw Error("--downsample " + std::to_string(src.downsample) + " is out of range: must be >= 1");
  *roi_lo = {0, 0, 0};
  *roi_hi = v.dims;
  if (!src.roi.empty()) {
    const auto r = parse_ints(src.roi, "--roi", 6);
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

void write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw Error(path + ": cannot open for writing");
    f << text;
    if (!f) throw Error(path + ": write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error(path + ": cannot rename temporary file (" + ec.message() + ")");
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
