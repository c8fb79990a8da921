#pragma once
// Sequential Dijkstra-order reference of the timestamped HP-ChainMail propagation (SPEC §4).
// Single-threaded, deliberately plain: used by the test suite to check the parallel solver
// (src/cpu/chainmail_propagate.cpp) and by the benchmark. Never used by the pipeline.
// Positions are displacements from rest (u = X - X0), as in every backend.
//
// The rule (docs/solver.md, "Propagation rule"), per non-FIXED element e with start
// position p0:
//   key of an element = (t, index), ordered lexicographically; FIXED elements have t = 0
//   and sit at their targets, everything else starts at t = +inf and p0.
//   Candidate times c = t_n + w(e,n) over neighbours with finite t, distinct, ascending.
//   For each c: S = { neighbours n with (t_n, n) < (c, e) }; pos = clamp(p0, S);
//   if pos != p0 then t_e = c, position = pos, stop. Otherwise t_e = +inf, position p0.
//   clamp(p0, S): per axis, intersect the link boxes of S; when that intersection is empty
//   use the box of the earliest member of S (by key); clamp p0's coordinate into it.
//   Exception: when the gap lo - hi is within solver::kGapTolerance * (1 + |lo|) (boxes that
//   touch in a point, separated by rounding only), the coordinate is the midpoint (lo + hi)/2.
#include <cstdint>
#include <limits>
#include <vector>

#include "hpcm/model.hpp"
#include "solver/rules.hpp"

namespace hpcm::reference {

inline constexpr float kInf = std::numeric_limits<float>::infinity();

struct ReferenceWave {
  std::vector<Vec3> pos;    ///< displacements from rest after the wave
  std::vector<float> time;  ///< arrival times: 0 for FIXED, +inf where the wave did not move e
  Index reached = 0;        ///< non-FIXED elements with a finite time
};

/// Axis interval [lo, hi] that the link between e and its neighbour n (at position pn) allows
/// for e's coordinate on axis b. `a` is the link's axis; `e_plus` is true when e is on the
/// + side of n (e = n + unit_a at rest); `L` is the link's limits. Written here a second time
/// on purpose, apart from core/link_box.hpp: the reference is the oracle the shared rules are
/// tested against, so it does not call them.
struct Interval {
  float lo, hi;
};
inline Interval link_interval(const LinkLimits& L, int a, bool e_plus, Vec3 pn, int b) {
  if (b != a) return {pn[b] - L.shear, pn[b] + L.shear};
  if (e_plus) return {pn[a] + L.min_stretch, pn[a] + L.max_stretch};
  return {pn[a] - L.max_stretch, pn[a] - L.min_stretch};
}

/// One of e's (up to 6) neighbours: index, link axis, whether e is on the + side, limits.
struct Neighbour {
  Index n;
  int axis;
  bool e_plus;
  LinkLimits L;
};
/// Fills `out` (size <= 6) with e's neighbours in the order -x, +x, -y, +y, -z, +z; returns the count.
int neighbours(const Model& m, Index e, Neighbour out[6]);

/// clamp(p0, S) of the rule for the neighbours nb[k] with use[k] set, at positions pos and
/// keys (time, index), inside the element's wall `wall` (solver::element_wall). Returns p0 when
/// no neighbour is used.
Vec3 clamp_against(const Vec3& p0, const Neighbour* nb, int count, const bool* use, const std::vector<Vec3>& pos,
                   const std::vector<float>& time, const solver::Wall& wall);

/// The Dijkstra-order wave: pop the smallest tentative key (c, e); skip if e is final;
/// clamp p0 against the final neighbours with a smaller key; if that moves e, e becomes
/// final with time c and pushes (c + w, n) for its non-final neighbours.
/// Works in place on a full position array (p0 on entry, the wave's result on exit) and
/// resets its own buffers lazily, so a wave costs what it touches, not the lattice size.
class DijkstraPropagator {
 public:
  /// `wall`: the boundary box (solver::make_wall; the default is unbounded).
  explicit DijkstraPropagator(const Model& m, const solver::Wall& wall = {});
  /// One wave. `fixed` are the sources (t = 0), `targets[k]` the position of fixed[k].
  /// Returns the number of non-FIXED elements the wave moved.
  Index run(std::vector<Vec3>& pos, const std::vector<Index>& fixed, const std::vector<Vec3>& targets);
  /// Arrival times of the last wave (0 for FIXED, +inf where it did not move an element).
  const std::vector<float>& time() const { return time_; }
  /// Heap pops of the last wave (including skipped entries).
  std::int64_t pops() const { return pops_; }

 private:
  struct Entry {
    float c;
    Index e;
  };
  struct Later {
    bool operator()(const Entry& a, const Entry& b) const { return a.c > b.c || (a.c == b.c && a.e > b.e); }
  };
  const Model& m_;
  solver::Wall wall_;
  std::vector<float> time_;
  std::vector<std::uint8_t> final_;
  std::vector<Index> touched_;  ///< elements whose time/final changed in the last run
  std::vector<Entry> heap_;
  std::int64_t pops_ = 0;
};

/// Convenience wrapper: one wave with a fresh propagator.
ReferenceWave dijkstra_propagate(const Model& m, const std::vector<Vec3>& p0, const std::vector<std::uint8_t>& flags,
                                 const std::vector<Vec3>& targets, const solver::Wall& wall = {});

/// Evaluates the rule directly for one non-FIXED element e, given the final times and
/// positions of its neighbours: returns e's (time, position). Used by the tests to check
/// that a wave (from any solver) is a fixed point of the rule.
struct RuleResult {
  float time;
  Vec3 pos;
};
RuleResult evaluate_rule(const Model& m, Index e, const std::vector<Vec3>& p0, const std::vector<Vec3>& pos,
                         const std::vector<float>& time, const solver::Wall& wall = {});

/// Largest box violation over the links that have an upstream side by the key (t, index):
/// every link except those between two FIXED (t = 0) or two unreached (t = +inf) elements.
/// 0 when all of them are inside their boxes.
float upstream_link_violation(const Model& m, const std::vector<Vec3>& pos, const std::vector<float>& time);

/// Box violation of the single link between i and its +a neighbour (0 when inside).
float link_violation(const Model& m, Index i, int a, const std::vector<Vec3>& pos);

}  // namespace hpcm::reference
