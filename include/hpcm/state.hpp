#pragma once
// Mutable per-element state: positions, velocities, arrival times, flags (SPEC §2).
#include <cstdint>
#include <vector>

#include "hpcm/model.hpp"

namespace hpcm {

enum ElementFlags : std::uint8_t {
  kFixed = 1,    ///< not moved by ChainMail or dynamics this frame (grabbed or anchored)
  kGrabbed = 2,  ///< held by the grab tool
  kAnchor = 4,   ///< anchored every frame (bone or border anchors)
};

struct State {
  std::vector<Vec3> pos;            ///< X, lattice units (frame-end positions)
  std::vector<Vec3> vel;            ///< V, lattice units per frame (persists between frames)
  std::vector<float> time;          ///< arrival time of the last wave (+inf: not reached)
  std::vector<std::uint8_t> flags;  ///< ElementFlags

  /// Rest state: X = X0, V = 0, t = +inf, no flags.
  static State rest(const Model& m);
};

/// Largest violation of any link box over the whole lattice (0 when consistent).
float max_link_violation(const Model& m, const std::vector<Vec3>& pos);

/// Fold check of a deformed lattice. Every cell (8 neighbouring elements) is a trilinear
/// hexahedron; at each of its 8 corners the determinant of the three edge vectors leaving the
/// corner (oriented along +x, +y, +z) is the cell's Jacobian there (1 at rest). A cell with a
/// corner determinant <= 0 is folded.
struct CellJacobianStats {
  float min_det = 1;   ///< smallest corner determinant over all cells (1 for a lattice without cells)
  Index folded = 0;    ///< cells with a corner determinant <= 0
  Index cells = 0;     ///< cells checked
};
CellJacobianStats cell_jacobian(const Model& m, const std::vector<Vec3>& pos);

}  // namespace hpcm
