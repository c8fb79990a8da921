// hpcm phantom: generate the built-in synthetic abdominal phantom, summarise or write it.
#include <cstdio>

#include "cli_common.hpp"
#include "memory_estimate.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::cli {

void register_phantom(CLI::App& app) {
  struct Opts {
    std::string size = "128,128,75";
    std::string variant = "standard";
    std::uint64_t seed = 1;
    float noise = 12.0f;
    bool summary = false;
    std::string params;
    std::string out;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("phantom", "Generate the synthetic abdominal phantom");
  cmd->add_option("--size", o->size, "NX,NY,NZ, each in [8, 4096]")->capture_default_str();
  add_seed_option(cmd, "--seed", o->seed, "Noise seed");
  cmd->add_option("--variant", o->variant,
                  "Anatomy: standard | thin-tissue | thick-fat | air-pockets | table | anisotropic (see docs/tuning.md)")
      ->capture_default_str();
  cmd->add_option("--noise", o->noise, "Noise standard deviation in HU, [0, 200]")->capture_default_str();
  cmd->add_flag("--summary", o->summary, "Print dims and the element count per tissue class");
  cmd->add_option("--params", o->params, "Parameter file (tissue thresholds for the summary)");
  cmd->add_option("--out", o->out, "Write the phantom volume (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd)");
  cmd->callback([o] {
    PhantomOptions po;
    po.dims = parse_int3(o->size, "--size", 8, 4096);
    po.seed = o->seed;
    po.noise_hu = o->noise;
    po.variant = parse_phantom_variant(o->variant, "--variant");
    if (!(o->noise >= 0 && o->noise <= 200)) throw Error("--noise " + std::to_string(o->noise) + " is out of range [0, 200]");
    const bool summary = o->summary || o->out.empty();
    // Read and validated even when only --out uses nothing of it: a bad file is never ignored.
    const Params p = load_params_option(o->params);
    if (!o->out.empty()) {
#if defined(HPCM_WITH_ITK)
      io::check_output_path(o->out);  // before generating: a bad destination fails at once
#else
      throw Error("--out: hpcm was built without ITK, cannot write volumes");
#endif
    }
    // The volume (4 bytes per voxel, twice while writing) and, for the summary, the model.
    check_lattice_memory(po.dims, summary ? kRunBytesPerElement : 8.0, "--size " + o->size);
    const Volume v = make_phantom(po);
    if (!o->out.empty()) {
#if defined(HPCM_WITH_ITK)
      io::write_volume(v, o->out);
      std::printf("wrote %s\n", o->out.c_str());
#else
      throw Error("--out: hpcm was built without ITK, cannot write volumes");
#endif
    }
    if (summary) {
      const Model m = build_model(v, p);
      std::printf("dims %d x %d x %d (%lld elements), spacing %.4g x %.4g x %.4g mm\n", v.dims.x, v.dims.y, v.dims.z,
                  static_cast<long long>(m.size()), v.spacing[0], v.spacing[1], v.spacing[2]);
      std::printf("thresholds t1 %.6g, t2 %.6g, t3 %.6g HU\n", p.tissue.t1, p.tissue.t2, p.tissue.t3);
      for (int t = 0; t < kTissueCount; ++t)
        std::printf("%-13s %10lld  (%.1f %%)\n", tissue_name(t), static_cast<long long>(m.class_count[t]),
                    100.0 * m.class_count[t] / m.size());
    }
  });
}

}  // namespace hpcm::cli
