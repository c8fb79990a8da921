#pragma once
// Mutable per-element state: displacements, velocities, arrival times, flags (SPEC §2).
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
  /// u = X - X0, lattice units: frame-end displacements from rest (X0: the element's lattice
  /// index). Stored instead of X so that the float step of a displacement does not depend on
  /// where the element sits (docs/solver.md, "Displacements from rest"); positions() gives X.
  std::vector<Vec3> disp;
  std::vector<Vec3> vel;            ///< V, lattice units per frame (persists between frames)
  std::vector<float> time;          ///< arrival time of the last wave (+inf: not reached)
  std::vector<std::uint8_t> flags;  ///< ElementFlags

  /// Rest state: u = 0, V = 0, t = +inf, no flags.
  static State rest(const Model& m);
};

/// Position X = X0 + u of element i, in double (exact for every float displacement).
struct Point3 {
  double x = 0, y = 0, z = 0;
  double operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
};
inline Point3 position_of(const Model& m, Index i, Vec3 u) {
  const Int3 c = m.coords(i);
  return {c.x + static_cast<double>(u.x), c.y + static_cast<double>(u.y), c.z + static_cast<double>(u.z)};
}
/// Every element's position X0 + u (double).
std::vector<Point3> positions(const Model& m, const std::vector<Vec3>& disp);

/// Largest violation of any link box over the whole lattice (0 when consistent), from the
/// displacements (link differences 1 + u_hi - u_lo, the same floats as the solver's check).
float max_link_violation(const Model& m, const std::vector<Vec3>& disp);

/// Fold check of a deformed lattice. Every cell (8 neighbouring elements) is a trilinear
/// hexahedron; at each of its 8 corners the determinant of the three edge vectors leaving the
/// corner (oriented along +x, +y, +z) is the cell's Jacobian there (1 at rest). A cell with a
/// corner determinant <= 0 is folded.
struct CellJacobianStats {
  float min_det = 1;   ///< smallest corner determinant over all cells (1 for a lattice without cells)
  Index folded = 0;    ///< cells with a corner determinant <= 0
  Index cells = 0;     ///< cells checked
};
/// From the displacements: edges unit_a + (u_next - u), in double.
CellJacobianStats cell_jacobian(const Model& m, const std::vector<Vec3>& disp);

/// max_link_violation and cell_jacobian of a sequence of displacement fields (the frames of a
/// run), recomputed only in the blocks of 4×4×4 elements around elements whose displacement
/// changed (bitwise) since the previous call: a frame moves a few bricks of a CT, and the
/// metrics then cost what the motion costs. A changed element dirties its block and the blocks
/// below it (their cells and links reach it); 4 recomputes less around the moving region than 8
/// (`hpcm experiment --phantom 64,64,48`: 10.0 → 8.0 s) and keeps the per-block bookkeeping small
/// (2 was slower: 8.8 s). The values are exactly the whole-lattice functions'
/// (a maximum, a minimum and a count do not depend on the order). One object per metric and
/// sequence: it keeps a copy of the last field (12 bytes per element). reset() when the
/// model's links change (tissue classes or tolerances); another lattice size resets by itself.
class IncrementalMetrics {
 public:
  float max_link_violation(const Model& m, const std::vector<Vec3>& disp);
  CellJacobianStats cell_jacobian(const Model& m, const std::vector<Vec3>& disp);
  void reset();

 private:
  static constexpr int kBlock = 4;  ///< block edge (elements)
  std::vector<int> dirty_blocks(const Model& m, const std::vector<Vec3>& disp);
  Int3 block_lo(int b) const;
  std::vector<Vec3> seen_;
  Int3 blocks_{0, 0, 0};
  std::vector<float> link_max_;
  std::vector<double> cell_min_;
  std::vector<Index> cell_folded_;
};

/// The determinant at one cell corner from the displacement differences along its three edges
/// (each oriented along +x, +y, +z): the unit rest edge plus the difference, in double.
inline double corner_determinant(Vec3 dx, Vec3 dy, Vec3 dz) {
  const double ex[3] = {1.0 + dx.x, dx.y, dx.z}, ey[3] = {dy.x, 1.0 + dy.y, dy.z}, ez[3] = {dz.x, dz.y, 1.0 + dz.z};
  return ex[0] * (ey[1] * ez[2] - ey[2] * ez[1]) - ex[1] * (ey[0] * ez[2] - ey[2] * ez[0]) +
         ex[2] * (ey[0] * ez[1] - ey[1] * ez[0]);
}

}  // namespace hpcm
