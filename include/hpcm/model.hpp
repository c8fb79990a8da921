#pragma once
// The static lattice Model (SPEC §2–3): one element per (down-sampled) voxel, its HU,
// tissue class, tolerance, and the limits of the three links to its +x, +y, +z neighbours.
// Link limits are stored compactly: a 16-bit index per link into a table of the material's
// limits at the pair's mean HU, quantized to a grid of at most 65,535 levels over the
// material's control-point range (1/16 HU for the default material; the material is constant
// outside that range). Every component reads links through this one table.
// The mutable State lives in state.hpp; solvers step one State into the next.
#include <array>
#include <string>
#include <vector>

#include "hpcm/params.hpp"
#include "hpcm/volume.hpp"

namespace hpcm {

/// Where an element lies relative to the body (SPEC §3, "The body, and what is not tissue").
enum class Region : std::uint8_t {
  Body = 0,           ///< the patient: counted in every per-class statistic and check
  OutsideAir = 1,     ///< outside the body, HU < -500 (air and its noise, foam): free, not counted
  OutsideObject = 2,  ///< outside the body, HU >= -500 (the CT table, pads): anchored like bone, not counted
};

/// The body search's outcome, for `hpcm info`, summary.json and the report.
struct BodySummary {
  enum class Search { NotSearched, Found, NoBody };
  Search search = Search::NotSearched;
  std::string method;           ///< how the body was found (empty when not searched)
  Index body = 0;               ///< elements in the body (every element when there is none)
  Index outside_air = 0;        ///< left out: outside the body, HU < -500
  Index outside_objects = 0;    ///< left out and anchored: outside the body, HU >= -500
  /// One line: how many elements were left out and why, or why none were.
  std::string describe() const;
};

struct Model {
  Int3 dims;
  std::array<double, 3> spacing{1, 1, 1};  ///< mm per lattice unit (after down-sampling)
  std::array<double, 3> origin{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<float> hu;
  std::vector<std::uint8_t> tissue;    ///< Tissue per element
  std::vector<float> tau;              ///< element tolerance (relaxation weights 1/(tau+1e-4))
  /// link_index[a][i]: entry of link_table for the link between i and its +a neighbour
  /// (kNoLink at the + border).
  std::array<std::vector<std::uint16_t>, 3> link_index;
  std::vector<LinkLimits> link_table;
  /// The tolerance each table entry was built from: link_table[k] is
  /// limits_from_tau(link_tau[k], w) (a backend may keep the tolerance per link instead of the
  /// index and rebuild the limits from it).
  std::vector<float> link_tau;
  static constexpr std::uint16_t kNoLink = 0;  ///< table entry of the missing links at the + border

  /// Limits of the link between i and its +a neighbour.
  const LinkLimits& link(int a, Index i) const { return link_table[link_index[a][static_cast<std::size_t>(i)]]; }
  std::array<Index, kTissueCount> class_count{};  ///< elements per class
  /// Region per element (see Region); empty when no body was found or searched: then every
  /// element is counted.
  std::vector<std::uint8_t> region;
  BodySummary body;
  /// Elements per class that the per-class statistics count: the body's (class_count without a body).
  std::array<Index, kTissueCount> counted_class_count{};
  /// Whether element i is counted in the per-class statistics and the motion checks.
  bool counted(Index i) const { return region.empty() || region[static_cast<std::size_t>(i)] == std::uint8_t(Region::Body); }
  /// Whether element i is an outside object (anchored like bone).
  bool outside_object(Index i) const {
    return !region.empty() && region[static_cast<std::size_t>(i)] == std::uint8_t(Region::OutsideObject);
  }

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

/// HU at and above which an element is not air for the body search and the §7 surface test.
constexpr float kBodyHu = -500.0f;

/// Sets m.region and m.body from a body mask on m's grid (1 = body; empty = not searched).
/// A mask without any body element means "no body": every element stays counted. Outside
/// elements are split by HU (kBodyHu) into outside air and outside objects. Call
/// rebuild_materials afterwards (it counts the classes). Throws if the mask has the wrong size.
void set_body(Model& m, const std::vector<std::uint8_t>& body_mask, const std::string& method);

/// The same summary for a volume (v.body on v's grid), without building a model.
BodySummary summarize_body(const Volume& v);

/// Re-derives tissue classes and link limits after a parameter change (same volume).
void rebuild_materials(Model& m, const Params& p);

/// The SPEC §7 grab centre: central axial slice, line x = Nx/2, walking from y = 0
/// posteriorly to the first element with HU >= -500. Throws if the line has none.
Index paper_grab_centre(const Model& m);

/// Physical length (mm) of an offset in lattice units: spacing and direction of m.
double offset_length_mm(const Model& m, Vec3 offset);
/// An offset given in millimetres along the lattice axes (LPS) in lattice units: divided by
/// m.spacing per axis.
Vec3 lattice_offset_of_mm(const Model& m, Vec3 offset_mm);

/// Fewest elements along every axis that a grab of `grab_radius` lattice units needs: the grab
/// holds the 2 floor(r) + 1 elements around its centre along an axis, and the tissue needs a
/// free, linked element on each side of them to deform at all: 2 floor(r) + 3 (5 at the
/// default radius 1.5). A thinner lattice would be all tool (or all border) along that axis.
int min_lattice_extent(float grab_radius);
/// Throws hpcm::Error starting with `what` when an axis of m is shorter than
/// min_lattice_extent(grab_radius), naming the lattice and the minimum.
void check_lattice_extent(const Model& m, float grab_radius, const std::string& what);

}  // namespace hpcm
