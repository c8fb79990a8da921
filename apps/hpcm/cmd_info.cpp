// hpcm info VOLUME: geometry, HU statistics, lattice size after --roi/--downsample and the
// elements per tissue class under the current thresholds (--params).
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "cli_common.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::cli {

namespace {
struct InfoOptions {
  VolumeSource source;
  std::string volume;  // positional
  std::string params;
};

void print_geometry(const char* label, const Volume& v) {
  std::printf("%-11s%dx%dx%d\n", label, v.dims.x, v.dims.y, v.dims.z);
  std::printf("%-11s%.6g x %.6g x %.6g mm\n", "spacing", v.spacing[0], v.spacing[1], v.spacing[2]);
  std::printf("%-11s%.6g, %.6g, %.6g mm (LPS, centre of voxel 0,0,0)\n", "origin", v.origin[0], v.origin[1], v.origin[2]);
  std::array<double, 9> d = v.direction;
  for (double& x : d) x += 0.0;  // no "-0"
  std::printf("%-11s[%.6g %.6g %.6g; %.6g %.6g %.6g; %.6g %.6g %.6g] (row-major, column a = index axis a)\n",
              "direction", d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8]);
}
}  // namespace

void register_info(CLI::App& app) {
  auto o = std::make_shared<InfoOptions>();
  auto* cmd = app.add_subcommand("info", "Describe a CT volume: geometry, HU range, lattice size, tissue classes");
  cmd->add_option("volume", o->volume, "CT volume file or DICOM series directory (or use --input / --phantom)");
  add_volume_options(cmd, o->source);
  cmd->add_option("--params", o->params, "Parameter file (TOML) whose tissue thresholds classify the elements");
  cmd->callback([o] {
    VolumeSource src = o->source;
    if (!o->volume.empty()) {
      if (!src.input.empty() || !src.phantom.empty())
        throw Error("info: give the volume either as VOLUME or as --input/--phantom, not both");
      src.input = o->volume;
    }
    if (src.input.empty() && src.phantom.empty())
      throw Error("info: no volume given (hpcm info VOLUME, or --phantom NX,NY,NZ)");
    const Params p = load_params_option(o->params);
    if (src.downsample < 1)
      throw Error("--downsample " + std::to_string(src.downsample) + " is out of range: must be >= 1");

    const Volume full = load_volume_full(src);
    // --roi / --downsample are checked before anything is printed.
    const bool reduced = src.downsample > 1 || !src.roi.empty();
    const Volume lat = reduced ? load_volume(src) : Volume{};
    const Volume& lattice = reduced ? lat : full;
    if (!src.input.empty()) {
      std::error_code ec;
      if (std::filesystem::is_directory(src.input, ec)) {
#if defined(HPCM_WITH_ITK)
        const auto series = io::list_dicom_series(src.input);
        // The series read: the one --series names (a UID or '#N' as listed), else the only CT one.
        std::size_t read = series.size();
        for (std::size_t i = 0; i < series.size(); ++i)
          if (src.series.empty() ? (read == series.size() && series[i].modality == "CT")
                                 : (src.series == series[i].uid || src.series == "#" + std::to_string(i + 1)))
            read = i;
        std::printf("%-11s%s (DICOM directory, %zu series)\n", "input", src.input.c_str(), series.size());
        for (std::size_t i = 0; i < series.size(); ++i) {
          const auto& s = series[i];
          std::printf("%-11s#%zu %s%s: %s, %d slices of %dx%d%s%s\n", "series", i + 1,
                      s.uid.empty() ? "<empty SeriesInstanceUID>" : s.uid.c_str(), i == read ? " [read]" : "",
                      s.modality.empty() ? "?" : s.modality.c_str(), s.files, s.columns, s.rows,
                      s.description.empty() ? "" : ", ", s.description.c_str());
        }
#endif
      } else {
        std::printf("%-11s%s\n", "input", src.input.c_str());
#if defined(HPCM_WITH_ITK)
        // NIfTI: which of sform, qform and pixdim gave the grid (nibabel's rule).
        if (const std::string g = io::nifti_geometry_source(src.input); !g.empty()) std::printf("%-11s%s\n", "affine", g.c_str());
#endif
      }
    } else {
      std::printf("%-11sphantom %s (variant %s, seed %llu)\n", "input", src.phantom.c_str(), src.phantom_variant.c_str(),
                  static_cast<unsigned long long>(src.seed));
    }
    print_geometry("dims", full);
    double sum = 0;
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (float h : full.hu) {
      lo = std::min(lo, h);
      hi = std::max(hi, h);
      sum += h;
    }
    std::printf("%-11smin %.6g  max %.6g  mean %.6g\n", "HU", lo, hi, sum / double(full.hu.size()));

    std::printf("%-11s%dx%dx%d = %lld elements (downsample %d, roi %s)\n", "lattice", lattice.dims.x, lattice.dims.y,
                lattice.dims.z, static_cast<long long>(lattice.size()), src.downsample, src.roi.empty() ? "none" : src.roi.c_str());
    if (reduced)
      std::printf("%-11s%.6g x %.6g x %.6g mm, origin %.6g, %.6g, %.6g mm\n", "lattice", lattice.spacing[0], lattice.spacing[1],
                  lattice.spacing[2], lattice.origin[0], lattice.origin[1], lattice.origin[2]);
    long long count[kTissueCount] = {};
    for (float h : lattice.hu) ++count[static_cast<int>(p.tissue.classify(h))];
    std::printf("%-11st1 %.6g  t2 %.6g  t3 %.6g (air < t1 <= skin_fat < t2 <= muscle_organ < t3 <= bone)\n",
                "thresholds", p.tissue.t1, p.tissue.t2, p.tissue.t3);
    for (int t = 0; t < kTissueCount; ++t)
      std::printf("  %-13s%12lld  %6.2f %%\n", tissue_name(t), count[t], 100.0 * double(count[t]) / double(lattice.size()));
    // SPEC §3: the elements the statistics will count, and what is left out.
    Volume searched;
    const Volume* with_body = &lattice;
#if defined(HPCM_WITH_ITK)
    if (!reduced) {  // the input as stored: searched as run and experiment will (a phantom's outline aside)
      searched.hu = lattice.hu;
      searched.dims = lattice.dims;
      searched.body = io::find_body(lattice);
      searched.body_method = io::kBodyMethod;
      with_body = &searched;
    }
#endif
    std::printf("%s\n", summarize_body(*with_body).describe().c_str());
  });
}

}  // namespace hpcm::cli
