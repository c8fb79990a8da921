#pragma once
// The static lattice Model (SPEC §2–3): one element per (down-sampled) voxel, its HU,
// tissue class, tolerance, and the limits of the three links to its +x, +y, +z neighbours.
// The mutable State lives in state.hpp; solvers step one State into the next.
#include <array>
#include <vector>

#include "hpcm/params.hpp"
#include "hpcm/volume.hpp"

namespace hpcm {

struct Model {
  Int3 dims;
  std::array<double, 3> spacing{1, 1, 1};  ///< mm per lattice unit (after down-sampling)
  std::array<double, 3> origin{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<float> hu;
  std::vector<std::uint8_t> tissue;    ///< Tissue per element
  std::vector<float> tau;              ///< element tolerance (relaxation weights 1/(tau+1e-4))
  /// link[a][i]: limits of the link between i and its +a neighbour (unused at the + border).
  std::array<std::vector<LinkLimits>, 3> link;
  std::array<Index, kTissueCount> class_count{};  ///< elements per class

  Index size() const { return static_cast<Index>(dims.x) * dims.y * dims.z; }
  Index index(int x, int y, int z) const { return x + static_cast<Index>(dims.x) * (y + static_cast<Index>(dims.y) * z); }
  Int3 coords(Index i) const {
    const int x = static_cast<int>(i % dims.x);
    const Index r = i / dims.x;
    return {x, static_cast<int>(r % dims.y), static_cast<int>(r / dims.y)};
  }
  Vec3 rest(Index i) const {
    const Int3 c = coords(i);
    return {float(c.x), float(c.y), float(c.z)};
  }
};

/// Builds the model from a volume (already cropped / down-sampled) and validated params.
/// Throws hpcm::Error on an empty volume or invalid params.
Model build_model(const Volume& v, const Params& p);

/// Re-derives tissue classes and link limits after a parameter change (same volume).
void rebuild_materials(Model& m, const Params& p);

/// The SPEC §7 grab centre: central axial slice, line x = Nx/2, walking from y = 0
/// posteriorly to the first element with HU >= -500. Throws if the line has none.
Index paper_grab_centre(const Model& m);

}  // namespace hpcm
